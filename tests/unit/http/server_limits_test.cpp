#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include <atomic>

#include "http_test_util.hpp"
#include "libs/http/client.hpp"
#include "raw_socket.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

void check_error(const RawResponse& response, int status, const std::string& code) {
  CHECK(response.status == status);
  CHECK(response.headers.at("connection") == "close");
  CHECK(response.headers.at("content-type") == "application/json");
  auto body = json::parse(response.body);
  CHECK(body["status"] == status);
  CHECK(body["code"] == code);
  CHECK(body["error"].is_string());
}

}  // namespace

TEST_CASE("413 for a body over the limit, without reading it, then close") {
  std::atomic<int> calls{0};
  http::ServerOptions options;
  options.body_limit = 16;
  StartedServer s(
      [&](http::Request&& request, http::Respond respond) {
        ++calls;
        respond(echo_response(request));
      },
      options);

  SUBCASE("a body at the limit is fine") {
    RawSocket raw(s.port);
    raw.send("POST / HTTP/1.1\r\nHost: h\r\nContent-Length: 16\r\n\r\n0123456789abcdef");
    CHECK(raw.read_response().status == 200);
    CHECK(calls == 1);
  }
  SUBCASE("Content-Length over the limit, body sent") {
    RawSocket raw(s.port);
    raw.send("POST / HTTP/1.1\r\nHost: h\r\nContent-Length: 17\r\n\r\n0123456789abcdefg");
    check_error(raw.read_response(), 413, "PAYLOAD_TOO_LARGE");
    CHECK(raw.wait_closed());
    CHECK(calls == 0);
  }
  SUBCASE("a huge Content-Length is refused from the header alone") {
    RawSocket raw(s.port);
    raw.send("POST / HTTP/1.1\r\nHost: h\r\nContent-Length: 1000000000000\r\n\r\n");
    check_error(raw.read_response(), 413, "PAYLOAD_TOO_LARGE");
    CHECK(raw.wait_closed());
    CHECK(calls == 0);
  }
  SUBCASE("a chunked body that grows over the limit") {
    RawSocket raw(s.port);
    raw.send("POST / HTTP/1.1\r\nHost: h\r\nTransfer-Encoding: chunked\r\n\r\n10\r\n0123456789abcdef\r\n");
    raw.send("4\r\nmore\r\n0\r\n\r\n");
    check_error(raw.read_response(), 413, "PAYLOAD_TOO_LARGE");
    CHECK(raw.wait_closed());
    CHECK(calls == 0);
  }
  SUBCASE("through the client, which reads the answer despite the close") {
    auto response = http::request("127.0.0.1", s.port, "POST", "/", std::string(1000, 'x'));
    CHECK(response.status == 413);
    CHECK(json::parse(response.body)["code"] == "PAYLOAD_TOO_LARGE");
    CHECK(calls == 0);
  }
}

TEST_CASE("400 for malformed requests, then close") {
  std::atomic<int> calls{0};
  StartedServer s([&](http::Request&&, http::Respond respond) {
    ++calls;
    respond(http::Response{});
  });
  SUBCASE("garbage bytes") {
    RawSocket raw(s.port);
    const char garbage[] = "\x16\x03\x01\x02\x00 garbage\r\n\r\n";
    raw.send(std::string(garbage, sizeof garbage - 1));
    check_error(raw.read_response(), 400, "BAD_REQUEST");
    CHECK(raw.wait_closed());
  }
  SUBCASE("a bad percent escape in the path") {
    RawSocket raw(s.port);
    raw.send("GET /a%zz HTTP/1.1\r\nHost: h\r\n\r\n");
    auto response = raw.read_response();
    check_error(response, 400, "BAD_REQUEST");
    CHECK(json::parse(response.body)["error"] == "bad percent-encoding in the request path");
    CHECK(raw.wait_closed());
  }
  SUBCASE("a target that is not a path") {
    RawSocket raw(s.port);
    raw.send("GET nowhere HTTP/1.1\r\nHost: h\r\n\r\n");
    check_error(raw.read_response(), 400, "BAD_REQUEST");
  }
  SUBCASE("an oversized header") {
    RawSocket raw(s.port);
    raw.send("GET / HTTP/1.1\r\nHost: h\r\nX-Big: " + std::string(20000, 'a') + "\r\n\r\n");
    check_error(raw.read_response(), 431, "BAD_REQUEST");
    CHECK(raw.wait_closed());
  }
  CHECK(calls == 0);
}

TEST_CASE("header timeout closes a connection that sends half a request") {
  http::ServerOptions options;
  options.header_timeout = 150ms;
  StartedServer s(echo_handler(), options);
  SUBCASE("half a header") {
    RawSocket raw(s.port);
    raw.send("GET / HTTP/1.1\r\nHost: h\r\n");
    std::string received;
    CHECK(raw.wait_closed(5000ms, &received));
    CHECK(received.empty());
  }
  SUBCASE("headers but half the body") {
    RawSocket raw(s.port);
    raw.send("POST / HTTP/1.1\r\nHost: h\r\nContent-Length: 10\r\n\r\n12345");
    std::string received;
    CHECK(raw.wait_closed(5000ms, &received));
    CHECK(received.empty());
  }
  SUBCASE("nothing at all") {
    RawSocket raw(s.port);
    CHECK(raw.wait_closed());
  }
}

TEST_CASE("idle timeout closes a kept-alive connection between requests") {
  http::ServerOptions options;
  options.idle_timeout = 150ms;
  StartedServer s(echo_handler(), options);
  RawSocket raw(s.port);
  raw.send("GET / HTTP/1.1\r\nHost: h\r\n\r\n");
  CHECK(raw.read_response().status == 200);
  std::string received;
  CHECK(raw.wait_closed(5000ms, &received));
  CHECK(received.empty());
}

TEST_CASE("connections beyond max_connections are closed at once") {
  http::ServerOptions options;
  options.max_connections = 1;
  StartedServer s(echo_handler(), options);
  RawSocket first(s.port);
  first.send("GET /1 HTTP/1.1\r\nHost: h\r\n\r\n");
  CHECK(first.read_response().status == 200);  // the first is admitted and counted

  RawSocket second(s.port);
  std::string received;
  CHECK(second.wait_closed(5000ms, &received));
  CHECK(received.empty());
  CHECK(s.server->connection_count() == 1);

  first.send("GET /2 HTTP/1.1\r\nHost: h\r\n\r\n");  // the admitted one still works
  CHECK(json::parse(first.read_response().body)["path"] == "/2");
}
