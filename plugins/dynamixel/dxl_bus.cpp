#include "dxl_bus.hpp"

#include <algorithm>
#include <array>

namespace rcand::plugins::dynamixel {

namespace {

constexpr std::size_t kStatusOverhead = 11;  // header 4, id, length 2, 0x55, error, CRC 2

std::string id_text(std::uint8_t id) { return "Dynamixel ID " + std::to_string(id); }

}  // namespace

const char* error_number_text(std::uint8_t number) {
  switch (number) {
    case 1: return "result fail";
    case 2: return "instruction error";
    case 3: return "CRC error";
    case 4: return "data range error";
    case 5: return "data length error";
    case 6: return "data limit error";
    case 7: return "access error";
    default: return "unknown error";
  }
}

DxlBus::DxlBus(std::shared_ptr<SerialLink> link, std::chrono::microseconds reply_margin)
    : link_(std::move(link)), margin_(reply_margin) {}

SerialLink::Clock::time_point DxlBus::deadline_for(std::size_t reply_bytes) const {
  // 10 bits a byte (start, 8 data, stop) at the line rate.
  const auto wire = std::chrono::microseconds(static_cast<long long>(reply_bytes) * 10'000'000 / link_->baud_rate());
  return SerialLink::Clock::now() + wire + margin_;
}

void DxlBus::send(std::span<const std::uint8_t> packet) {
  // Late replies of an abandoned transaction must not be taken for this one's.
  link_->discard_input();
  decoder_.clear();
  const auto wire = std::chrono::microseconds(static_cast<long long>(packet.size()) * 10'000'000 / link_->baud_rate());
  link_->write(packet, SerialLink::Clock::now() + wire + margin_);
}

std::optional<Packet> DxlBus::receive(std::uint8_t id, SerialLink::Clock::time_point until) {
  std::array<std::uint8_t, 256> chunk{};
  for (;;) {
    while (auto packet = decoder_.next())
      if (packet->code == inst::kStatus && !packet->params.empty() && (id == kBroadcastId || packet->id == id))
        return packet;  // (anything else is an echo or another servo's late reply: skip it)
    const std::size_t n = link_->read_some(chunk, until);
    if (n == 0) return std::nullopt;
    decoder_.feed(std::span(chunk).first(n));
  }
}

Packet DxlBus::expect(std::uint8_t id, std::size_t reply_params, const char* what) {
  auto reply = receive(id, deadline_for(kStatusOverhead + reply_params));
  if (!reply)
    throw DxlError(DxlError::Kind::NoReply, id,
                   "no answer from " + id_text(id) + " (" + what + ") at " + std::to_string(link_->baud_rate()) + " bps on " +
                       link_->path() + ": check power (X-series need 12 V on the bus), the ID, the baud rate and the cable");
  const std::uint8_t number = reply->params[0] & 0x7F;
  if (number != 0)
    throw DxlError(DxlError::Kind::ServoError, id, id_text(id) + " refused " + what + ": " + error_number_text(number));
  if (reply->params.size() != 1 + reply_params)
    throw DxlError(DxlError::Kind::BadReply, id,
                   id_text(id) + " answered " + what + " with " + std::to_string(reply->params.size() - 1) + " bytes, expected " +
                       std::to_string(reply_params));
  return std::move(*reply);
}

PingReply DxlBus::ping(std::uint8_t id, unsigned tries) {
  const std::string what = tries > 1 ? "ping, " + std::to_string(tries) + " tries" : "ping";
  for (unsigned attempt = 1;; ++attempt) {
    send(encode(id, inst::kPing, {}));
    try {
      const auto reply = expect(id, 3, what.c_str());
      return {id, get_u16(reply.params, 1), reply.params[3], (reply.params[0] & kAlertBit) != 0};
    } catch (const DxlError& e) {
      if (e.kind() != DxlError::Kind::NoReply || attempt >= tries) throw;
    }
  }
}

std::vector<PingReply> DxlBus::scan() {
  send(encode(kBroadcastId, inst::kPing, {}));
  std::vector<PingReply> found;
  // Every possible ID answers in turn; the wait restarts with each answer.
  while (auto reply = receive(kBroadcastId, deadline_for(kStatusOverhead + 3))) {
    // (a second answer from one ID is the late reply to a ping sent before the scan)
    const bool listed = std::any_of(found.begin(), found.end(), [&](const PingReply& p) { return p.id == reply->id; });
    if (reply->params.size() == 4 && !listed)
      found.push_back({reply->id, get_u16(reply->params, 1), reply->params[3], (reply->params[0] & kAlertBit) != 0});
  }
  std::sort(found.begin(), found.end(), [](const PingReply& a, const PingReply& b) { return a.id < b.id; });
  return found;
}

std::vector<std::uint8_t> DxlBus::read(std::uint8_t id, std::uint16_t address, std::uint16_t length, bool* alert) {
  std::vector<std::uint8_t> params;
  put_u16(params, address);
  put_u16(params, length);
  send(encode(id, inst::kRead, params));
  auto reply = expect(id, length, "a read");
  if (alert) *alert = (reply.params[0] & kAlertBit) != 0;
  return {reply.params.begin() + 1, reply.params.end()};
}

void DxlBus::write(std::uint8_t id, std::uint16_t address, std::span<const std::uint8_t> data, bool* alert) {
  std::vector<std::uint8_t> params;
  put_u16(params, address);
  params.insert(params.end(), data.begin(), data.end());
  send(encode(id, inst::kWrite, params));
  const auto reply = expect(id, 0, "a write");
  if (alert) *alert = (reply.params[0] & kAlertBit) != 0;
}

void DxlBus::reboot(std::uint8_t id) {
  send(encode(id, inst::kReboot, {}));
  expect(id, 0, "reboot");
}

void DxlBus::sync_write(std::uint16_t address, std::uint16_t length,
                        const std::vector<std::pair<std::uint8_t, std::vector<std::uint8_t>>>& items) {
  std::vector<std::uint8_t> params;
  params.reserve(4 + items.size() * (1 + length));
  put_u16(params, address);
  put_u16(params, length);
  for (const auto& [id, data] : items) {
    if (data.size() != length)
      throw std::invalid_argument("sync write: every servo's data must be " + std::to_string(length) + " bytes");
    params.push_back(id);
    params.insert(params.end(), data.begin(), data.end());
  }
  send(encode(kBroadcastId, inst::kSyncWrite, params));
}

SyncReadResult DxlBus::sync_read(std::uint16_t address, std::uint16_t length, const std::vector<std::uint8_t>& ids) {
  std::vector<std::uint8_t> params;
  put_u16(params, address);
  put_u16(params, length);
  params.insert(params.end(), ids.begin(), ids.end());
  send(encode(kBroadcastId, inst::kSyncRead, params));
  SyncReadResult result;
  result.data.resize(ids.size());
  std::size_t answered = 0;
  // The servos answer in the order asked, each after the one before; one timeout covers them all, so a missing
  // servo costs one margin, not one per servo after it.
  const auto until = deadline_for(ids.size() * (kStatusOverhead + length));
  while (answered < ids.size()) {
    auto reply = receive(kBroadcastId, until);
    if (!reply) break;
    for (std::size_t i = 0; i < ids.size(); ++i) {
      if (ids[i] != reply->id || result.data[i]) continue;
      if ((reply->params[0] & 0x7F) == 0 && reply->params.size() == 1u + length)
        result.data[i] = std::vector<std::uint8_t>(reply->params.begin() + 1, reply->params.end());
      if (reply->params[0] & kAlertBit) result.alerted.push_back(reply->id);
      ++answered;
      break;
    }
  }
  return result;
}

}  // namespace rcand::plugins::dynamixel
