// The host's side of a stream route (sdk::StreamRoute) of an isolated capability: the plugin's handler gets a
// StreamWriter whose calls become messages to rcand, where the client's real writer is (stream_relay.hpp). Frames go
// through the frame ring once, however many viewers they are pushed to. rcand tells the host when a client left and,
// at each heartbeat, each stream's counters, so closed() and counters() answer from here without a round trip. start()
// alone waits for rcand's answer (it is false when rcand's caps refuse the client, and a plugin admits viewers by it).
#pragma once

#include <nlohmann/json.hpp>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>

#include "libs/isolation/channel.hpp"
#include "libs/isolation/frame_ring.hpp"
#include "rcand/sdk/stream.hpp"

namespace rcand::isolation {

class RemoteStreams {
 public:
  static constexpr std::chrono::milliseconds kStartAnswer{2000};

  RemoteStreams(Channel& channel, FrameRing* ring) : channel_(channel), ring_(ring) {}

  // The writer for rcand's stream `id` (a "stream" message), for the plugin's handler.
  std::shared_ptr<sdk::StreamWriter> open(std::uint64_t id);
  // rcand's "s_state" message: the streams closed, and the counters of the others.
  void update(const nlohmann::json& state);
  // rcand's "s_started" message: whether a start() went through.
  void started(const nlohmann::json& answer);
  // The channel ended: every stream is closed.
  void close_all();

 private:
  class Writer;
  // A writer's start(): `message` sent, rcand's answer awaited (false: the channel ended, or no answer in time).
  bool start(std::uint64_t id, const nlohmann::json& message);

  Channel& channel_;
  FrameRing* ring_;
  std::mutex mutex_;
  std::condition_variable answered_;
  bool ended_ = false;
  std::map<std::uint64_t, std::weak_ptr<Writer>> writers_;
  std::map<std::uint64_t, std::optional<bool>> starts_;  // by stream id: one start() at a time per stream
};

}  // namespace rcand::isolation
