// rcanctl fleet stop's one MQTT publish (rcanctl/mqtt_publish_once.cpp) keeps its --timeout when the broker's host
// drops the connection attempt: a listening socket whose backlog is full drops every further SYN, as a firewall or a
// swamped broker does, and a blocking connect() would wait out the kernel's SYN retries (about two minutes).
#include <doctest/doctest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <vector>

#include "mqtt_publish_once.hpp"

namespace {

struct Fd {
  int fd = -1;
  explicit Fd(int f) : fd(f) {}
  Fd(Fd&& other) noexcept : fd(other.fd) { other.fd = -1; }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

sockaddr_in loopback(std::uint16_t port) {
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(port);
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  return address;
}

}  // namespace

TEST_CASE("rcanctl fleet stop: a broker that never completes the TCP handshake fails within --timeout") {
  Fd listener(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0));
  REQUIRE(listener.fd >= 0);
  sockaddr_in address = loopback(0);
  REQUIRE(::bind(listener.fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0);
  REQUIRE(::listen(listener.fd, 0) == 0);
  socklen_t length = sizeof address;
  REQUIRE(::getsockname(listener.fd, reinterpret_cast<sockaddr*>(&address), &length) == 0);
  const std::uint16_t port = ntohs(address.sin_port);
  // Fill the accept queue (never accepted): from here on the listener drops SYNs.
  std::vector<Fd> queued;
  for (int i = 0; i < 2; ++i) {
    queued.emplace_back(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0));
    REQUIRE(queued.back().fd >= 0);
    sockaddr_in to = loopback(port);
    const int rc = ::connect(queued.back().fd, reinterpret_cast<sockaddr*>(&to), sizeof to);
    CHECK((rc == 0 || errno == EINPROGRESS));  // non-blocking: the handshake completes (or is dropped) later
  }

  rcand::rcanctl::MqttBrokerOptions options;
  options.host = "127.0.0.1";
  options.port = port;
  options.client_id = "rcanctl-publish-once-test";
  options.timeout = std::chrono::milliseconds(1000);
  const auto started = std::chrono::steady_clock::now();
  const auto result = rcand::rcanctl::mqtt_publish_once(options, "r2r/broadcast", "{}");
  const auto took = std::chrono::steady_clock::now() - started;
  CHECK_FALSE(result.acknowledged);
  CHECK(result.error.find("within the timeout") != std::string::npos);
  // Generous (the bound is 1 s): a blocking connect would wait out the SYN retries, over a minute.
  CHECK(took < std::chrono::seconds(10));
}
