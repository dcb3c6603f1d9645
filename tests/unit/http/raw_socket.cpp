#include "raw_socket.hpp"

// GCC 12 with -fsanitize=address reports a false maybe-uninitialized inside Beast's response parser (a
// boost::optional in basic_parser::do_field); the library code it flags is not ours.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <boost/beast/http/parser.hpp>
#include <boost/beast/http/string_body.hpp>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace rcand::test {

namespace bhttp = boost::beast::http;

namespace {

sockaddr_in loopback(std::uint16_t port) {
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(port);
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  return address;
}

std::string lower(std::string text) {
  for (char& c : text) {
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  }
  return text;
}

}  // namespace

RawSocket::RawSocket(std::uint16_t port) {
  fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd_ < 0) throw std::runtime_error(std::string{"socket: "} + std::strerror(errno));
  auto address = loopback(port);
  if (::connect(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    auto error = errno;
    ::close(fd_);
    throw std::runtime_error(std::string{"connect: "} + std::strerror(error));
  }
}

RawSocket::~RawSocket() { close(); }

void RawSocket::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

void RawSocket::send(std::string_view data) {
  while (!data.empty()) {
    auto sent = ::send(fd_, data.data(), data.size(), MSG_NOSIGNAL);
    if (sent < 0) {
      if (errno == EINTR) continue;
      throw std::runtime_error(std::string{"send: "} + std::strerror(errno));
    }
    data.remove_prefix(static_cast<std::size_t>(sent));
  }
}

long RawSocket::receive_some(std::chrono::steady_clock::time_point deadline) {
  for (;;) {
    auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() < 0) return -1;
    pollfd entry{fd_, POLLIN, 0};
    int ready = ::poll(&entry, 1, static_cast<int>(left.count()) + 1);
    if (ready < 0 && errno == EINTR) continue;
    if (ready <= 0) return -1;
    char chunk[16384];
    auto got = ::recv(fd_, chunk, sizeof chunk, 0);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) return 0;  // EOF or reset
    pending_.append(chunk, static_cast<std::size_t>(got));
    return got;
  }
}

RawResponse RawSocket::read_response(std::chrono::milliseconds limit) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  bhttp::response_parser<bhttp::string_body> parser;
  parser.eager(true);
  for (;;) {
    if (!pending_.empty()) {
      boost::beast::error_code ec;
      auto used = parser.put(boost::asio::buffer(pending_.data(), pending_.size()), ec);
      pending_.erase(0, used);
      if (ec && ec != bhttp::error::need_more) throw std::runtime_error("bad response: " + ec.message());
      if (parser.is_done()) break;
      if (used > 0 && !pending_.empty()) continue;
    }
    auto got = receive_some(deadline);
    if (got < 0) throw std::runtime_error("no complete response in time");
    if (got == 0) {
      boost::beast::error_code ec;
      parser.put_eof(ec);
      if (ec || !parser.is_done()) throw std::runtime_error("connection closed before a complete response");
      break;
    }
  }
  auto message = parser.release();
  RawResponse response;
  response.status = static_cast<int>(message.result_int());
  for (const auto& field : message) {
    auto name = lower(std::string{field.name_string()});
    auto [it, inserted] = response.headers.try_emplace(name, std::string{field.value()});
    if (!inserted) it->second += ", " + std::string{field.value()};
  }
  response.body = std::move(message.body());
  return response;
}

bool RawSocket::wait_closed(std::chrono::milliseconds limit, std::string* received) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  for (;;) {
    auto got = receive_some(deadline);
    if (got <= 0) {
      if (received) received->append(pending_);
      pending_.clear();
      return got == 0;
    }
  }
}

SilentListener::SilentListener() {
  fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  auto address = loopback(0);
  if (fd_ < 0 || ::bind(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 || ::listen(fd_, 8) != 0) {
    throw std::runtime_error(std::string{"silent listener: "} + std::strerror(errno));
  }
  socklen_t length = sizeof address;
  ::getsockname(fd_, reinterpret_cast<sockaddr*>(&address), &length);
  port_ = ntohs(address.sin_port);
}

SilentListener::~SilentListener() {
  if (fd_ >= 0) ::close(fd_);
}

std::uint16_t unused_port() {
  int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  auto address = loopback(0);
  ::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address);
  socklen_t length = sizeof address;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length);
  ::close(fd);
  return ntohs(address.sin_port);
}

}  // namespace rcand::test
