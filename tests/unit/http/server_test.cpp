#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include <mutex>
#include <stdexcept>
#include <vector>

#include "http_test_util.hpp"
#include "libs/http/client.hpp"
#include "raw_socket.hpp"

using namespace rcand::test;
using nlohmann::json;

TEST_CASE("GET round-trip: path and query are decoded, header names lower-cased") {
  StartedServer s(echo_handler());
  http::Client client("127.0.0.1", s.port);
  const std::string target = "/a%20b/c%2Fd?x=1&y=hello+world&z=%2F&x=2&flag";
  auto response = client.request("GET", target, {}, {{"X-Custom-Header", "Value"}});
  CHECK(response.status == 200);
  CHECK(response.headers.at("server") == "rcand");
  CHECK(response.headers.at("content-type") == "application/json");
  CHECK(response.headers.at("content-length") == std::to_string(response.body.size()));

  auto seen = json::parse(response.body);
  CHECK(seen["method"] == "GET");
  CHECK(seen["target"] == target);
  CHECK(seen["path"] == "/a b/c/d");
  CHECK(seen["query"] == json{{"x", "1"}, {"y", "hello world"}, {"z", "/"}, {"flag", ""}});
  CHECK(seen["headers"]["x-custom-header"] == "Value");
  CHECK(seen["headers"].contains("host"));
  CHECK(seen["body"] == "");
  CHECK(seen["remote"].get<std::string>().rfind("127.0.0.1:", 0) == 0);
}

TEST_CASE("POST round-trip carries the body; repeated headers joined") {
  StartedServer s(echo_handler());
  {
    auto response = http::request("127.0.0.1", s.port, "POST", "/api/action", R"({"type":"move"})");
    CHECK(response.status == 200);
    auto seen = json::parse(response.body);
    CHECK(seen["method"] == "POST");
    CHECK(seen["body"] == R"({"type":"move"})");
    CHECK(seen["headers"]["content-type"] == "application/json");
    CHECK(seen["headers"]["content-length"] == "15");
  }
  {
    RawSocket raw(s.port);
    raw.send("POST /x HTTP/1.1\r\nHost: h\r\nX-Dup: a\r\nx-dup: b\r\nContent-Length: 5\r\n\r\nhello");
    auto response = raw.read_response();
    CHECK(response.status == 200);
    auto seen = json::parse(response.body);
    CHECK(seen["method"] == "POST");
    CHECK(seen["body"] == "hello");
    CHECK(seen["headers"]["x-dup"] == "a, b");
  }
}

TEST_CASE("two requests on one keep-alive connection use one connection") {
  std::mutex mutex;
  std::vector<std::string> remotes;
  StartedServer s([&](http::Request&& request, http::Respond respond) {
    {
      std::lock_guard lock(mutex);
      remotes.push_back(request.remote);
    }
    respond(http::Response{200, "text/plain", "ok", {}});
  });
  http::Client client("127.0.0.1", s.port);
  CHECK(client.request("GET", "/one").body == "ok");
  CHECK(client.request("GET", "/two").body == "ok");
  CHECK(s.server->connection_count() == 1);
  std::lock_guard lock(mutex);
  REQUIRE(remotes.size() == 2);
  CHECK(remotes[0] == remotes[1]);
}

TEST_CASE("HTTP/1.0 keep-alive is honoured when asked for") {
  StartedServer s(echo_handler());
  RawSocket raw(s.port);
  raw.send("GET /a HTTP/1.0\r\nConnection: keep-alive\r\n\r\n");
  auto first = raw.read_response();
  CHECK(first.status == 200);
  CHECK(first.headers.at("connection") == "keep-alive");
  raw.send("GET /b HTTP/1.0\r\nConnection: keep-alive\r\n\r\n");
  CHECK(json::parse(raw.read_response().body)["path"] == "/b");
  CHECK(s.server->connection_count() == 1);
}

TEST_CASE("pipelined requests are answered in order") {
  StartedServer s(echo_handler());
  RawSocket raw(s.port);
  raw.send("GET /first HTTP/1.1\r\nHost: h\r\n\r\nGET /second HTTP/1.1\r\nHost: h\r\n\r\n");
  CHECK(json::parse(raw.read_response().body)["path"] == "/first");
  CHECK(json::parse(raw.read_response().body)["path"] == "/second");
}

TEST_CASE("Connection: close is honoured") {
  StartedServer s(echo_handler());
  SUBCASE("HTTP/1.1 with Connection: close") {
    RawSocket raw(s.port);
    raw.send("GET / HTTP/1.1\r\nHost: h\r\nConnection: close\r\n\r\n");
    auto response = raw.read_response();
    CHECK(response.status == 200);
    CHECK(response.headers.at("connection") == "close");
    std::string rest;
    CHECK(raw.wait_closed(5000ms, &rest));
    CHECK(rest.empty());
  }
  SUBCASE("HTTP/1.0 without keep-alive") {
    RawSocket raw(s.port);
    raw.send("GET / HTTP/1.0\r\n\r\n");
    CHECK(raw.read_response().status == 200);
    CHECK(raw.wait_closed());
  }
  SUBCASE("the handler asks to close") {
    StartedServer closing([](http::Request&&, http::Respond respond) {
      respond(http::Response{200, "text/plain", "bye", {{"Connection", "close"}}});
    });
    RawSocket raw(closing.port);
    raw.send("GET / HTTP/1.1\r\nHost: h\r\n\r\n");
    auto response = raw.read_response();
    CHECK(response.body == "bye");
    CHECK(response.headers.at("connection") == "close");
    CHECK(raw.wait_closed());
  }
}

TEST_CASE("Expect: 100-continue gets an interim answer before the body is sent") {
  StartedServer s(echo_handler());
  RawSocket raw(s.port);
  raw.send("POST /up HTTP/1.1\r\nHost: h\r\nContent-Length: 4\r\nExpect: 100-continue\r\n\r\n");
  CHECK(raw.read_response().status == 100);
  raw.send("data");
  auto response = raw.read_response();
  CHECK(response.status == 200);
  CHECK(json::parse(response.body)["body"] == "data");
}

TEST_CASE("HEAD gets the Content-Length of the body without the body") {
  StartedServer s([](http::Request&&, http::Respond respond) { respond(http::Response{200, "text/plain", "12345", {}}); });
  http::Client client("127.0.0.1", s.port);
  auto response = client.request("HEAD", "/");
  CHECK(response.status == 200);
  CHECK(response.headers.at("content-length") == "5");
  CHECK(response.body.empty());
  CHECK(client.request("GET", "/").body == "12345");  // the connection is still in step
}

TEST_CASE("extra response headers are sent; unsafe ones are dropped") {
  StartedServer s([](http::Request&&, http::Respond respond) {
    respond(http::Response{201, "text/plain", "made",
                           {{"Location", "/things/1"}, {"X-Evil", "a\r\nSet-Cookie: x=1"}, {"Content-Length", "99"}}});
  });
  http::Client client("127.0.0.1", s.port);
  auto response = client.request("GET", "/");
  CHECK(response.status == 201);
  CHECK(response.body == "made");
  CHECK(response.headers.at("location") == "/things/1");
  CHECK(response.headers.count("x-evil") == 0);
  CHECK(response.headers.count("set-cookie") == 0);
  CHECK(response.headers.at("content-length") == "4");
}

TEST_CASE("an invalid status from the handler becomes a 500") {
  StartedServer s([](http::Request&&, http::Respond respond) { respond(http::Response{42, "text/plain", "x", {}}); });
  auto response = http::request("127.0.0.1", s.port, "GET", "/");
  CHECK(response.status == 500);
  CHECK(json::parse(response.body)["code"] == "INTERNAL");
}

TEST_CASE("start() reports a taken port clearly") {
  StartedServer first(echo_handler());
  http::ServerOptions options;
  options.port = first.port;
  http::Server second(options, echo_handler());
  CHECK_THROWS_WITH_AS(second.start(),
                       ("cannot listen on 127.0.0.1:" + std::to_string(first.port) + ": Address already in use").c_str(),
                       std::runtime_error);
}

TEST_CASE("bad options are refused naming the option") {
  http::ServerOptions options;
  options.io_threads = 0;
  CHECK_THROWS_WITH_AS(http::Server(options, echo_handler()),
                       "http server option io_threads must be between 1 and 256, got 0", std::invalid_argument);
  options = {};
  options.header_timeout = 0ms;
  CHECK_THROWS_WITH_AS(http::Server(options, echo_handler()), doctest::Contains("header_timeout"),
                       std::invalid_argument);
  options = {};
  CHECK_THROWS_AS(http::Server(options, http::Handler{}), std::invalid_argument);
  options.address = "not an address!";
  http::Server server(options, echo_handler());
  CHECK_THROWS_WITH_AS(server.start(), doctest::Contains("cannot listen on not an address!:0"), std::runtime_error);
}

TEST_CASE("stop() with open idle connections returns and closes them") {
  StartedServer s(echo_handler());
  RawSocket used(s.port);
  used.send("GET / HTTP/1.1\r\nHost: h\r\n\r\n");
  CHECK(used.read_response().status == 200);
  RawSocket idle1(s.port);
  RawSocket idle2(s.port);
  RawSocket half(s.port);
  half.send("GET / HTTP/1.1\r\nHo");

  s.server->stop();
  CHECK(used.wait_closed());
  CHECK(idle1.wait_closed());
  CHECK(idle2.wait_closed());
  CHECK(half.wait_closed());
  CHECK(s.server->connection_count() == 0);
  s.server->stop();  // idempotent
  CHECK_THROWS_AS(RawSocket{s.port}, std::runtime_error);  // no longer listening
}
