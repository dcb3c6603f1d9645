// One end of the channel between rcand and an isolated capability's host process (rcand-plugin-host): a Unix
// SOCK_SEQPACKET socket, so every send is one message and a receive never sees half of one. Each message is a JSON
// object in MessagePack (nlohmann-json's encoding, no parser of ours), its type under "t".
#pragma once

#include <nlohmann/json.hpp>

#include <cstddef>
#include <mutex>
#include <optional>
#include <string>
#include <utility>

namespace rcand::isolation {

class Channel {
 public:
  // The largest message either side sends or accepts: a bigger answer is refused at its sender with a named error.
  static constexpr std::size_t kMaxMessage = 4u << 20;

  explicit Channel(int fd);  // takes ownership; sizes the socket's buffers for kMaxMessage
  ~Channel();
  Channel(const Channel&) = delete;
  Channel& operator=(const Channel&) = delete;

  // A connected pair (rcand's end first, the host's end second), both close-on-exec.
  static std::pair<int, int> socket_pair();

  // Any thread (sends are serialized). false: the peer is gone, or the message is over kMaxMessage (`error` says), or
  // with `wait` false the peer's buffer is full (a peer that stopped reading never holds the sender).
  bool send(const nlohmann::json& message, std::string* error = nullptr, bool wait = true) noexcept;
  // One thread at a time. The next message; nullopt once the peer closed its end or shutdown() ran. A message that
  // does not decode is skipped and logged (the peer is ours, but a bug in it must not stop the reader).
  std::optional<nlohmann::json> receive();
  // Any thread: a receive() blocked now returns nullopt; sends fail from now on.
  void shutdown() noexcept;
  int fd() const noexcept { return fd_; }

 private:
  int fd_;
  std::mutex send_mutex_;
};

}  // namespace rcand::isolation
