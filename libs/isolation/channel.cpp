#include "libs/isolation/channel.hpp"

#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <stdexcept>
#include <system_error>
#include <vector>

#include "libs/base/logging.hpp"

namespace rcand::isolation {

Channel::Channel(int fd) : fd_(fd) {
  const int size = static_cast<int>(kMaxMessage + 4096);
  ::setsockopt(fd_, SOL_SOCKET, SO_SNDBUF, &size, sizeof size);
  ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &size, sizeof size);
}

Channel::~Channel() { ::close(fd_); }

std::pair<int, int> Channel::socket_pair() {
  int fds[2];
  if (::socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, fds) != 0)
    throw std::system_error(errno, std::generic_category(), "socketpair for an isolated capability");
  return {fds[0], fds[1]};
}

bool Channel::send(const nlohmann::json& message, std::string* error, bool wait) noexcept {
  try {
    const std::vector<std::uint8_t> bytes = nlohmann::json::to_msgpack(message);
    if (bytes.size() > kMaxMessage) {
      if (error != nullptr)
        *error = "message of " + std::to_string(bytes.size()) + " bytes is over the isolated channel's limit of " +
                 std::to_string(kMaxMessage) + " bytes";
      return false;
    }
    std::lock_guard lock(send_mutex_);
    for (;;) {
      const ssize_t sent = ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL | (wait ? 0 : MSG_DONTWAIT));
      if (sent == static_cast<ssize_t>(bytes.size())) return true;
      if (sent < 0 && errno == EINTR) continue;
      if (error != nullptr) *error = errno == EAGAIN ? "the peer is not reading" : "the channel is closed";
      return false;
    }
  } catch (const std::exception& e) {  // a string that is not UTF-8 cannot be encoded
    if (error != nullptr) *error = std::string("message cannot be encoded: ") + e.what();
    return false;
  }
}

std::optional<nlohmann::json> Channel::receive() {
  std::vector<std::uint8_t> buffer;
  for (;;) {
    // The size of the next message first (MSG_TRUNC reports the whole length), then the message itself.
    std::uint8_t probe = 0;
    const ssize_t size = ::recv(fd_, &probe, 1, MSG_PEEK | MSG_TRUNC);
    if (size < 0 && errno == EINTR) continue;
    if (size <= 0) return std::nullopt;
    buffer.resize(static_cast<std::size_t>(size));
    const ssize_t got = ::recv(fd_, buffer.data(), buffer.size(), 0);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) return std::nullopt;
    try {
      auto message = nlohmann::json::from_msgpack(buffer);
      if (message.is_object() && message.contains("t")) return message;
    } catch (const std::exception&) {
    }
    logger("isolation")->error("a message of {} bytes on an isolated capability's channel does not decode; skipped", got);
  }
}

void Channel::shutdown() noexcept { ::shutdown(fd_, SHUT_RDWR); }

}  // namespace rcand::isolation
