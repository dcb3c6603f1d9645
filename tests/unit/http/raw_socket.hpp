// Plain POSIX sockets for tests that must misbehave (half requests, garbage, pipelining) or watch for a close.
// Every wait is on the socket itself (poll), bounded by a generous limit so a bug fails the test instead of hanging.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <string>
#include <string_view>

namespace rcand::test {

using namespace std::chrono_literals;

struct RawResponse {
  int status = 0;
  std::map<std::string, std::string> headers;  // lower-cased names
  std::string body;
};

class RawSocket {
 public:
  explicit RawSocket(std::uint16_t port);  // connects to 127.0.0.1:port
  ~RawSocket();
  RawSocket(const RawSocket&) = delete;
  RawSocket& operator=(const RawSocket&) = delete;

  void send(std::string_view data);
  // One HTTP response; throws std::runtime_error when none arrives within `limit` or the peer closes first.
  RawResponse read_response(std::chrono::milliseconds limit = 5000ms);
  // Reads until the peer closes (EOF or reset): true then, false when `limit` passed first. Bytes read are appended
  // to `received` when given.
  bool wait_closed(std::chrono::milliseconds limit = 5000ms, std::string* received = nullptr);
  void close();

 private:
  // Appends what arrives; 0 on EOF/reset, -1 on timeout.
  long receive_some(std::chrono::steady_clock::time_point deadline);

  int fd_ = -1;
  std::string pending_;
};

// A socket that listens on 127.0.0.1 and never accepts: connections complete in the backlog and are never answered.
class SilentListener {
 public:
  SilentListener();
  ~SilentListener();
  SilentListener(const SilentListener&) = delete;
  SilentListener& operator=(const SilentListener&) = delete;
  std::uint16_t port() const noexcept { return port_; }

 private:
  int fd_ = -1;
  std::uint16_t port_ = 0;
};

// A port on 127.0.0.1 that nothing listens on (bound, read, released).
std::uint16_t unused_port();

}  // namespace rcand::test
