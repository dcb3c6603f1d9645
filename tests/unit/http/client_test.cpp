#include <doctest/doctest.h>

#include <chrono>

#include "http_test_util.hpp"
#include "libs/http/client.hpp"
#include "raw_socket.hpp"

using namespace rcand::test;

namespace {

std::string error_of(const std::function<void()>& action) {
  try {
    action();
  } catch (const http::ClientError& e) {
    return e.what();
  }
  return "(no ClientError)";
}

}  // namespace

TEST_CASE("Client times out against a listener that never answers") {
  SilentListener silent;
  http::Client client("127.0.0.1", silent.port(), 300ms);
  const auto began = std::chrono::steady_clock::now();
  auto message = error_of([&] { client.request("GET", "/api/status?token=s3cret"); });
  const auto took = std::chrono::steady_clock::now() - began;
  CHECK(message == "GET /api/status on 127.0.0.1:" + std::to_string(silent.port()) + ": timed out after 300 ms");
  CHECK(took >= 300ms);
  CHECK(took < 3000ms);
}

TEST_CASE("Client reports a refused connection clearly") {
  const auto port = unused_port();
  auto message = error_of([&] { http::request("127.0.0.1", port, "GET", "/x?token=s3cret"); });
  CHECK(message == "cannot connect to 127.0.0.1:" + std::to_string(port) + ": Connection refused");
}

TEST_CASE("Client refuses to send malformed requests") {
  http::Client client("127.0.0.1", unused_port());
  CHECK(error_of([&] { client.request("GE T", "/"); }) == "invalid HTTP method 'GE T'");
  CHECK(error_of([&] { client.request("GET", "/a b"); }).find("invalid request target") == 0);
  CHECK(error_of([&] { client.request("GET", "/", {}, {{"X-A", "1\r\nX-B: 2"}}); }).find("holds CR, LF or NUL") !=
        std::string::npos);
}

TEST_CASE("Client reconnects when the server closed its kept-alive connection") {
  auto first = std::make_unique<StartedServer>(
      [](http::Request&&, http::Respond respond) { respond(http::Response{200, "text/plain", "first", {}}); });
  const auto port = first->port;
  http::Client client("127.0.0.1", port);
  CHECK(client.request("GET", "/").body == "first");

  first.reset();  // closes the connection the client keeps
  http::ServerOptions options;
  options.port = port;
  http::Server second(options, [](http::Request&&, http::Respond respond) {
    respond(http::Response{200, "text/plain", "second", {}});
  });
  REQUIRE(second.start() == port);
  CHECK(client.request("POST", "/", "{}").body == "second");
  CHECK(client.request("GET", "/").body == "second");
  CHECK(second.connection_count() == 1);
}

TEST_CASE("request() uses a one-shot connection") {
  StartedServer s(echo_handler());
  auto response = http::request("127.0.0.1", s.port, "GET", "/");
  CHECK(response.status == 200);
  CHECK(response.headers.at("connection") == "close");
}
