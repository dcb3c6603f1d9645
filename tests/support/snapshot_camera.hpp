// A snapshot camera on 127.0.0.1 for the vision tests and bench (tests/integration/vision/vision_snapshot_test.cpp,
// bench/vision_bench.cpp): GET /snapshot.jpg answered with one JPEG per request on kept-alive HTTP/1.1 connections,
// or 404 on demand. Header-only, POSIX.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace rcand::test {

// Every GET is answered with `jpeg` (200) or 404, on a kept-alive connection. Made
// on a given port, it binds that one (SO_REUSEADDR): the camera that went away comes back where it was.
class SnapshotCamera {
 public:
  explicit SnapshotCamera(std::string jpeg, std::uint16_t port = 0) : jpeg_(std::move(jpeg)) {
    listener_ = ::socket(AF_INET, SOCK_STREAM, 0);
    if (listener_ < 0) throw std::runtime_error("snapshot camera: socket failed");
    const int yes = 1;
    ::setsockopt(listener_, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(port);
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::bind(listener_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 || ::listen(listener_, 8) != 0) {
      ::close(listener_);
      throw std::runtime_error("snapshot camera: cannot listen on 127.0.0.1:" + std::to_string(port));
    }
    socklen_t length = sizeof address;
    ::getsockname(listener_, reinterpret_cast<sockaddr*>(&address), &length);
    port_ = ntohs(address.sin_port);
    acceptor_ = std::thread([this] { accept_loop(); });
  }
  ~SnapshotCamera() {
    {
      std::lock_guard lock(mutex_);
      stopping_ = true;
      for (int fd : clients_) ::shutdown(fd, SHUT_RDWR);
    }
    ::shutdown(listener_, SHUT_RDWR);  // wakes accept()
    acceptor_.join();
    for (auto& server : servers_) server.join();
    ::close(listener_);
  }

  std::uint16_t port() const { return port_; }
  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_) + "/snapshot.jpg"; }
  void answer_not_found(bool not_found) { not_found_ = not_found; }
  int connections() const { return connections_; }
  int requests() const { return requests_; }
  // The head of the last request (request line and headers).
  std::string last_request() {
    std::lock_guard lock(mutex_);
    return last_request_;
  }

 private:
  void accept_loop() {
    while (true) {
      const int fd = ::accept(listener_, nullptr, nullptr);
      std::lock_guard lock(mutex_);
      if (fd < 0 || stopping_) {
        if (fd >= 0) ::close(fd);
        return;
      }
      ++connections_;
      clients_.push_back(fd);
      servers_.emplace_back([this, fd] { serve(fd); });
    }
  }

  // Request after request on one connection, until the client or the destructor closes it.
  void serve(int fd) {
    std::string pending;
    char buffer[2048];
    while (true) {
      const auto end = pending.find("\r\n\r\n");
      if (end == std::string::npos) {
        const ssize_t got = ::recv(fd, buffer, sizeof buffer, 0);
        if (got <= 0) break;
        pending.append(buffer, static_cast<std::size_t>(got));
        continue;
      }
      const bool get = pending.starts_with("GET /snapshot.jpg HTTP/1.1\r\n");
      {
        std::lock_guard lock(mutex_);
        last_request_ = pending.substr(0, end);
      }
      pending.erase(0, end + 4);
      ++requests_;
      const std::string answer =
          !get || not_found_
              ? std::string("HTTP/1.1 404 Not Found\r\nContent-Type: text/plain\r\nContent-Length: 9\r\n\r\nnot found")
              : "HTTP/1.1 200 OK\r\nContent-Type: image/jpeg\r\nContent-Length: " + std::to_string(jpeg_.size()) + "\r\n\r\n" +
                    jpeg_;
      if (::send(fd, answer.data(), answer.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(answer.size())) break;
    }
    std::lock_guard lock(mutex_);  // forgotten before it is closed: the destructor never shuts a reused number down
    std::erase(clients_, fd);
    ::close(fd);
  }

  std::string jpeg_, last_request_;
  int listener_ = -1;
  std::uint16_t port_ = 0;
  std::atomic<bool> not_found_{false};
  std::atomic<int> connections_{0}, requests_{0};
  std::thread acceptor_;
  std::mutex mutex_;
  bool stopping_ = false;
  std::vector<int> clients_;
  std::vector<std::thread> servers_;
};

}  // namespace rcand::test
