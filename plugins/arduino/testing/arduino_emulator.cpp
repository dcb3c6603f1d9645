#include "arduino_emulator.hpp"

#include <poll.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include <algorithm>

namespace rcand::plugins::arduino::testing {

namespace {
constexpr auto kBridgeFirmwareWatchdog = std::chrono::milliseconds(1000);  // STOP_TIMEOUT_MS
}

ArduinoEmulator::ArduinoEmulator(int master, std::chrono::milliseconds boot_delay)
    : master_(master), boot_delay_(boot_delay), thread_([this] { loop(); }) {}

ArduinoEmulator::~ArduinoEmulator() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  thread_.join();
}

void ArduinoEmulator::set_distance_mm(std::int64_t mm) {
  std::lock_guard lock(mutex_);
  distance_mm_ = mm;
}
void ArduinoEmulator::set_hung(bool hung) {
  std::lock_guard lock(mutex_);
  hung_ = hung;
}
void ArduinoEmulator::set_silent(bool silent) {
  std::lock_guard lock(mutex_);
  silent_ = silent;
}
ArduinoEmulator::Board ArduinoEmulator::board() const {
  std::lock_guard lock(mutex_);
  return board_;
}
std::vector<ArduinoEmulator::Line> ArduinoEmulator::received() const {
  std::lock_guard lock(mutex_);
  return received_;
}
void ArduinoEmulator::clear_received() {
  std::lock_guard lock(mutex_);
  received_.clear();
}

bool ArduinoEmulator::wait_until(const std::function<bool(const Board&, const std::vector<Line>&)>& predicate,
                                 std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  return changed_.wait_for(lock, timeout, [&] { return predicate(board_, received_); });
}

void ArduinoEmulator::reply(const std::string& text) {
  if (silent_) return;
  const std::string line = text + "\n";  // Serial.println writes "\r\n"; the firmware's own serializeJson + '\n' not
  (void)!::write(master_, line.data(), line.size());
}

void ArduinoEmulator::handle(const std::string& raw, Clock::time_point now) {
  // Serial.readStringUntil('\n') then trim(): an empty line is not a command and does not feed the watchdog.
  const auto first = raw.find_first_not_of(" \t\r");
  if (first == std::string::npos) return;
  const std::string line = raw.substr(first, raw.find_last_not_of(" \t\r") - first + 1);
  last_line_ = now;
  received_.push_back({now, line});
  const nlohmann::json doc = nlohmann::json::parse(line, nullptr, false);
  if (doc.is_discarded() || line.size() > kMaxLineBytes) return reply(R"({"error":"json parse error"})");
  const auto text = [&](const char* key) {
    return doc.is_object() && doc.contains(key) && doc[key].is_string() ? doc[key].get<std::string>() : "";
  };
  const auto number = [&](const char* key, int fallback) {
    return doc.is_object() && doc.contains(key) && doc[key].is_number() ? doc[key].get<int>() : fallback;
  };
  const std::string cmd = text("cmd");
  if (cmd == "drive") {
    board_.left = std::clamp(number("left", 0), -255, 255);
    board_.right = std::clamp(number("right", 0), -255, 255);
    reply(R"({"ack":true})");
  } else if (cmd == "stop") {
    board_.left = board_.right = 0;
    reply(R"({"ack":true})");
  } else if (cmd == "ping") {
    reply(R"({"ack":true})");
  } else if (cmd == "sensor") {
    if (text("id") == "hcsr04") reply(nlohmann::json{{"sensor", "hcsr04"}, {"distance_mm", distance_mm_}}.dump());
    else reply(R"({"error":"unknown sensor id"})");
  } else if (cmd == "servo") {
    board_.servo_pin = number("pin", 3);
    board_.servo_angle = std::clamp(number("angle", 90), 0, 180);
    reply(R"({"ack":true})");
  } else {
    reply(R"({"error":"unknown command"})");
  }
}

void ArduinoEmulator::loop() {
  for (;;) {
    pollfd pfd{master_, POLLIN, 0};
    const int ready = ::poll(&pfd, 1, 2);
    const auto now = Clock::now();
    std::unique_lock lock(mutex_);
    if (stop_) return;
    const bool open = ready <= 0 || (pfd.revents & POLLHUP) == 0;
    if (open && !board_.port_open) {  // DTR rises: the board resets and its bootloader runs
      board_.left = board_.right = 0;
      ++board_.boots;
      board_.booting = boot_delay_.count() > 0;
      boot_until_ = now + boot_delay_;
      partial_.clear();
      last_line_ = now;
    }
    board_.port_open = open;
    if (board_.booting && now >= boot_until_) board_.booting = false;
    if (open && !hung_ && (pfd.revents & POLLIN)) {
      char buffer[512];
      const ssize_t n = ::read(master_, buffer, sizeof buffer);
      if (n > 0 && !board_.booting) {
        partial_.append(buffer, static_cast<std::size_t>(n));
        for (auto end = partial_.find('\n'); end != std::string::npos; end = partial_.find('\n')) {
          const std::string line = partial_.substr(0, end);
          partial_.erase(0, end + 1);
          handle(line, now);
        }
      }
    }
    // The firmware's loop(): silent for more than STOP_TIMEOUT_MS -> stopMotors().
    if (board_.moving() && now - last_line_ > kBridgeFirmwareWatchdog) {
      board_.left = board_.right = 0;
      ++board_.watchdog_stops;
      board_.watchdog_stopped_at = now;
    }
    changed_.notify_all();
    const bool idle = !open || hung_;  // poll() returns at once on a hang-up, and on unread input while hung
    lock.unlock();
    if (idle) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
}

}  // namespace rcand::plugins::arduino::testing
