// An MJPEG viewer as a browser's <img> is one: GET /api/stream/mjpeg on a plain socket, then one multipart part at a
// time (its headers and its JPEG), read with bounded waits (poll), never more than asked for. For the vision
// integration test and bench/vision_bench.cpp. Header-only, POSIX.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cctype>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>

namespace rcand::test {

class MjpegClient {
 public:
  struct Part {
    std::map<std::string, std::string> headers;  // lower-cased names
    std::string body;
    std::chrono::steady_clock::time_point received;  // when its last byte arrived
  };

  // Connects to 127.0.0.1:`port`; `receive_buffer` > 0 sets SO_RCVBUF first (a client with little room).
  explicit MjpegClient(std::uint16_t port, int receive_buffer = 0) {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd_ < 0) throw std::runtime_error("socket failed");
    if (receive_buffer > 0) ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof receive_buffer);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(port);
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
      ::close(fd_);
      throw std::runtime_error("connect failed");
    }
  }
  ~MjpegClient() { close(); }
  MjpegClient(const MjpegClient&) = delete;
  MjpegClient& operator=(const MjpegClient&) = delete;

  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

  // Sends the request and reads the answer's status and headers. `bearer` empty: no Authorization header.
  int open(const std::string& target, const std::string& bearer = {}, std::chrono::milliseconds limit = std::chrono::seconds(5)) {
    std::string request = "GET " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\n";
    if (!bearer.empty()) request += "Authorization: Bearer " + bearer + "\r\n";
    request += "\r\n";
    if (::send(fd_, request.data(), request.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(request.size()))
      throw std::runtime_error("send failed");
    const auto deadline = std::chrono::steady_clock::now() + limit;
    std::string head;
    try {
      head = read_until("\r\n\r\n", deadline);
    } catch (const Closed&) {
      throw std::runtime_error("no answer to GET " + target);
    }
    status_ = std::stoi(head.substr(9, 3));
    headers_ = parse_headers(head.substr(head.find("\r\n") + 2));
    return status_;
  }
  int status() const noexcept { return status_; }
  const std::map<std::string, std::string>& headers() const noexcept { return headers_; }
  std::string header(const std::string& lower_name) const {
    const auto it = headers_.find(lower_name);
    return it == headers_.end() ? std::string() : it->second;
  }

  // A non-streamed answer's body (Content-Length).
  std::string body(std::chrono::milliseconds limit = std::chrono::seconds(5)) {
    const auto length = std::stoul(header("content-length"));
    try {
      return read_exactly(length, std::chrono::steady_clock::now() + limit);
    } catch (const Closed&) {
      throw std::runtime_error("the body ended early");
    }
  }

  // The next part of a multipart answer; nullopt when the server closed or `limit` passed first.
  std::optional<Part> next_part(std::chrono::milliseconds limit = std::chrono::seconds(5)) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    try {
      std::string head = read_until("\r\n\r\n", deadline);
      const auto boundary = head.find("--");
      if (boundary == std::string::npos) throw std::runtime_error("no boundary before a part");
      head = head.substr(head.find("\r\n", boundary) + 2);
      Part part;
      part.headers = parse_headers(head);
      part.body = read_exactly(std::stoul(part.headers.at("content-length")), deadline);
      part.received = std::chrono::steady_clock::now();
      return part;
    } catch (const std::out_of_range&) {
      throw std::runtime_error("a part without Content-Length");
    } catch (const Closed&) {
      return std::nullopt;
    }
  }

 private:
  struct Closed {};

  static std::map<std::string, std::string> parse_headers(const std::string& block) {
    std::map<std::string, std::string> headers;
    std::size_t at = 0;
    while (at < block.size()) {
      const auto end = block.find("\r\n", at);
      const std::string line = block.substr(at, end == std::string::npos ? std::string::npos : end - at);
      at = end == std::string::npos ? block.size() : end + 2;
      const auto colon = line.find(':');
      if (colon == std::string::npos) continue;
      std::string name = line.substr(0, colon);
      for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      headers[name] = line.substr(line.find_first_not_of(' ', colon + 1));
    }
    return headers;
  }

  // Reads into buffer_ until it holds `needle`; returns everything up to and including it.
  std::string read_until(const std::string& needle, std::chrono::steady_clock::time_point deadline) {
    std::size_t found;
    while ((found = buffer_.find(needle)) == std::string::npos) fill(deadline);
    std::string out = buffer_.substr(0, found + needle.size());
    buffer_.erase(0, found + needle.size());
    return out;
  }
  std::string read_exactly(std::size_t length, std::chrono::steady_clock::time_point deadline) {
    while (buffer_.size() < length) fill(deadline);
    std::string out = buffer_.substr(0, length);
    buffer_.erase(0, length);
    return out;
  }
  void fill(std::chrono::steady_clock::time_point deadline) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    pollfd fd{fd_, POLLIN, 0};
    if (left.count() <= 0 || ::poll(&fd, 1, static_cast<int>(left.count())) <= 0) throw Closed{};
    char chunk[64 * 1024];
    const ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
    if (n <= 0) throw Closed{};
    buffer_.append(chunk, static_cast<std::size_t>(n));
  }

  int fd_ = -1;
  int status_ = 0;
  std::map<std::string, std::string> headers_;
  std::string buffer_;
};

}  // namespace rcand::test
