#include "feetech_bus.hpp"

#include <array>

namespace rcand::plugins::feetech {

namespace {

constexpr std::size_t kFeetechStatusOverhead = 6;  // FF FF, id, length, error, checksum

}  // namespace

FeetechBus::FeetechBus(std::shared_ptr<SerialLink> link, std::chrono::microseconds reply_margin, unsigned retries)
    : link_(std::move(link)), margin_(reply_margin), retries_(retries) {}

SerialLink::Clock::time_point FeetechBus::deadline_for(std::size_t reply_bytes) const {
  // 10 bits a byte (start, 8 data, stop) at the line rate.
  const auto wire = std::chrono::microseconds(static_cast<long long>(reply_bytes) * 10'000'000 / link_->baud_rate());
  return SerialLink::Clock::now() + wire + margin_;
}

void FeetechBus::send(std::span<const std::uint8_t> packet) {
  // Late replies of an abandoned transaction must not be taken for this one's.
  link_->discard_input();
  decoder_.clear();
  const auto wire = std::chrono::microseconds(static_cast<long long>(packet.size()) * 10'000'000 / link_->baud_rate());
  link_->write(packet, SerialLink::Clock::now() + wire + margin_);
}

std::optional<Packet> FeetechBus::receive(std::uint8_t id, SerialLink::Clock::time_point until) {
  std::array<std::uint8_t, 256> chunk{};
  for (;;) {
    while (auto packet = decoder_.next())
      if (id == kBroadcastId || packet->id == id) return packet;  // (anything else is another servo's late reply)
    const std::size_t n = link_->read_some(chunk, until);
    if (n == 0) return std::nullopt;
    decoder_.feed(std::span(chunk).first(n));
  }
}

Packet FeetechBus::transact(std::uint8_t id, const std::vector<std::uint8_t>& packet, std::size_t reply_params,
                            const char* what) {
  for (unsigned attempt = 0;; ++attempt) {
    send(packet);
    auto reply = receive(id, deadline_for(kFeetechStatusOverhead + reply_params));
    if (reply && reply->params.size() == reply_params) return std::move(*reply);
    if (reply && attempt >= retries_)
      throw FeetechError(FeetechError::Kind::BadReply, id,
                         "Feetech servo ID " + std::to_string(id) + " answered " + what + " with " +
                             std::to_string(reply->params.size()) + " bytes, expected " + std::to_string(reply_params));
    if (attempt >= retries_)
      throw FeetechError(FeetechError::Kind::NoReply, id,
                         "no answer from Feetech servo ID " + std::to_string(id) + " (" + what + ", " +
                             std::to_string(retries_ + 1) + " tries) at " + std::to_string(link_->baud_rate()) + " bps on " +
                             link_->path() + ": check its power, its ID, the baud rate and the cable");
  }
}

std::uint8_t FeetechBus::ping(std::uint8_t id) { return transact(id, encode(id, inst::kPing, {}), 0, "ping").code; }

std::vector<std::uint8_t> FeetechBus::read(std::uint8_t id, std::uint8_t address, std::uint8_t length, std::uint8_t* error) {
  const std::array<std::uint8_t, 2> params{address, length};
  auto reply = transact(id, encode(id, inst::kRead, params), length, "a read");
  if (error) *error = reply.code;
  return std::move(reply.params);
}

void FeetechBus::write(std::uint8_t id, std::uint8_t address, std::span<const std::uint8_t> data) {
  std::vector<std::uint8_t> params{address};
  params.insert(params.end(), data.begin(), data.end());
  transact(id, encode(id, inst::kWrite, params), 0, "a write");
}

void FeetechBus::sync_write(std::uint8_t address, std::uint8_t length, const SyncItems& items) {
  std::vector<std::uint8_t> params{address, length};
  params.reserve(2 + items.size() * (1u + length));
  for (const auto& [id, data] : items) {
    if (data.size() != length)
      throw std::invalid_argument("sync write: every servo's data must be " + std::to_string(length) + " bytes");
    params.push_back(id);
    params.insert(params.end(), data.begin(), data.end());
  }
  if (params.size() + 2 > 0xFF) throw std::invalid_argument("sync write: more than one packet's worth of servos");
  send(encode(kBroadcastId, inst::kSyncWrite, params));
}

SyncReadResult FeetechBus::sync_read(std::uint8_t address, std::uint8_t length, const std::vector<std::uint8_t>& ids) {
  std::vector<std::uint8_t> params{address, length};
  params.insert(params.end(), ids.begin(), ids.end());
  send(encode(kBroadcastId, inst::kSyncRead, params));
  SyncReadResult result;
  result.data.resize(ids.size());
  std::size_t answered = 0;
  // The servos answer in the order asked, each after the one before; one timeout covers them all, so a missing
  // servo costs one margin, not one per servo after it.
  const auto until = deadline_for(ids.size() * (kFeetechStatusOverhead + length));
  while (answered < ids.size()) {
    auto reply = receive(kBroadcastId, until);
    if (!reply) break;
    for (std::size_t i = 0; i < ids.size(); ++i) {
      if (ids[i] != reply->id || result.data[i]) continue;
      if (reply->params.size() == length) result.data[i] = std::move(reply->params);
      if (reply->code != 0) result.errors.emplace_back(reply->id, reply->code);
      ++answered;
      break;
    }
  }
  return result;
}

}  // namespace rcand::plugins::feetech
