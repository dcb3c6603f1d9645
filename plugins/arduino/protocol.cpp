#include "protocol.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>

namespace rcand::plugins::arduino {

namespace {

using nlohmann::json;

std::string arduino_line(const json& object) { return object.dump() + "\n"; }

std::string_view arduino_trimmed(std::string_view text) {
  const auto first = text.find_first_not_of(" \t\r");
  if (first == std::string_view::npos) return {};
  const auto last = text.find_last_not_of(" \t\r");
  return text.substr(first, last - first + 1);
}

}  // namespace

std::string drive_line(int left, int right) {
  return arduino_line(
      {{"cmd", "drive"}, {"left", std::clamp(left, -kMaxPwm, kMaxPwm)}, {"right", std::clamp(right, -kMaxPwm, kMaxPwm)}});
}
std::string stop_line() { return arduino_line({{"cmd", "stop"}}); }
std::string ping_line() { return arduino_line({{"cmd", "ping"}}); }
std::string sensor_line(std::string_view id) { return arduino_line({{"cmd", "sensor"}, {"id", std::string(id)}}); }
std::string servo_line(int pin, int angle) {
  return arduino_line({{"cmd", "servo"}, {"pin", pin}, {"angle", std::clamp(angle, 0, 180)}});
}

Reply parse_reply(std::string_view line) {
  Reply reply;
  const json doc = json::parse(arduino_trimmed(line), nullptr, false);
  if (doc.is_discarded() || !doc.is_object()) {
    reply.error = "not a JSON object";
    return reply;
  }
  if (const auto ack = doc.find("ack"); ack != doc.end()) {
    if (ack->is_boolean() && ack->get<bool>()) reply.kind = Reply::Kind::Ack;
    else reply.error = "ack is not true";
    return reply;
  }
  if (const auto error = doc.find("error"); error != doc.end()) {
    reply.kind = Reply::Kind::Error;
    reply.error = error->is_string() ? error->get<std::string>() : error->dump();
    return reply;
  }
  if (const auto sensor = doc.find("sensor"); sensor != doc.end() && sensor->is_string()) {
    reply.kind = Reply::Kind::Sensor;
    reply.sensor = sensor->get<std::string>();
    if (const auto d = doc.find("distance_mm"); d != doc.end() && d->is_number_integer())
      reply.distance_mm = d->get<std::int64_t>();
    return reply;
  }
  reply.error = "neither ack, error nor sensor";
  return reply;
}

void LineSplitter::feed(std::string_view bytes) {
  for (const char c : bytes) {
    if (c == '\n') {
      if (!skipping_ && !arduino_trimmed(buffer_).empty()) pending_ += std::string(arduino_trimmed(buffer_)) + '\n';
      buffer_.clear();
      skipping_ = false;
      continue;
    }
    if (skipping_) continue;
    buffer_.push_back(c);
    if (buffer_.size() > kMaxLineBytes) {
      buffer_.clear();
      skipping_ = true;
      ++overlong_;
    }
  }
}

std::optional<std::string> LineSplitter::next() {
  const auto end = pending_.find('\n');
  if (end == std::string::npos) return std::nullopt;
  std::string line = pending_.substr(0, end);
  pending_.erase(0, end + 1);
  return line;
}

void LineSplitter::clear() {
  buffer_.clear();
  pending_.clear();
  skipping_ = false;
}

}  // namespace rcand::plugins::arduino
