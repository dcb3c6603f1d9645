// ServerOptions::priority (the e-stop lane), the connection limits and the busy lane, the header checks, and the
// screen every request meets first.
#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include <pthread.h>

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <vector>

#include "http_test_util.hpp"
#include "libs/http/upgrade.hpp"
#include "raw_socket.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

bool is_stop_request(const http::Request& request) { return request.method == "POST" && request.path == "/stop"; }

http::ServerOptions priority_options() {
  http::ServerOptions options;
  options.priority = is_stop_request;
  return options;
}

constexpr const char* kStop = "POST /stop HTTP/1.1\r\nHost: h\r\nContent-Length: 0\r\n\r\n";
constexpr const char* kGet = "GET /x HTTP/1.1\r\nHost: h\r\n\r\n";

// A handler whose "/block" requests hold their worker thread until release() (a plugin that hangs, say).
struct BlockingHandler {
  std::mutex mutex;
  std::condition_variable changed;
  int blocked = 0;
  bool released = false;

  http::Handler handler() {
    return [this](http::Request&& request, http::Respond respond) {
      if (request.path == "/block") {
        std::unique_lock lock(mutex);
        ++blocked;
        changed.notify_all();
        changed.wait(lock, [this] { return released; });
      }
      respond(echo_response(request));
    };
  }
  void wait_blocked(int count) {
    std::unique_lock lock(mutex);
    REQUIRE(changed.wait_for(lock, 5s, [&] { return blocked >= count; }));
  }
  void release() {
    std::lock_guard lock(mutex);
    released = true;
    changed.notify_all();
  }
};

}  // namespace

TEST_CASE("a priority request is answered while every worker loop is held by other work") {
  BlockingHandler blocking;
  auto options = priority_options();
  options.io_threads = 1;
  StartedServer s(blocking.handler(), options);
  RawSocket busy(s.port);
  busy.send("GET /block HTTP/1.1\r\nHost: h\r\n\r\n");
  blocking.wait_blocked(1);  // the only worker is now stuck in the handler

  RawSocket stop(s.port);
  stop.send(kStop);
  const auto answer = stop.read_response();
  CHECK(answer.status == 200);
  CHECK(json::parse(answer.body)["path"] == "/stop");

  blocking.release();
  CHECK(busy.read_response().status == 200);
}

TEST_CASE("a connection stays on the accept thread while it sends priority requests, then moves to a worker") {
  // The handler answers with the name of the thread it ran on.
  StartedServer s(
      [](http::Request&& request, http::Respond respond) {
        char name[16] = {};
        pthread_getname_np(pthread_self(), name, sizeof name);
        auto response = echo_response(request);
        response.body = json{{"path", request.path}, {"thread", name}, {"body", request.body}}.dump();
        respond(std::move(response));
      },
      priority_options());
  RawSocket raw(s.port);
  for (int i = 0; i < 2; ++i) {
    raw.send(kStop);
    CHECK(json::parse(raw.read_response().body)["thread"] == "http.accept");
  }
  raw.send(kGet);
  const auto moved = json::parse(raw.read_response().body);
  CHECK(moved["path"] == "/x");
  CHECK(moved["thread"].get<std::string>().rfind("http.io.", 0) == 0);
  raw.send(kStop);  // for good: a later stop on it is the worker's
  CHECK(json::parse(raw.read_response().body)["thread"].get<std::string>().rfind("http.io.", 0) == 0);
  raw.send(std::string(kGet) + "GET /y HTTP/1.1\r\nHost: h\r\nContent-Length: 3\r\n\r\nabc");  // pipelined
  CHECK(json::parse(raw.read_response().body)["path"] == "/x");
  auto second = json::parse(raw.read_response().body);
  CHECK(second["path"] == "/y");
  CHECK(second["body"] == "abc");
  CHECK(s.server->connection_count() == 1);
}

TEST_CASE("beyond max_connections a priority request is answered and anything else gets 503 with Retry-After") {
  auto options = priority_options();
  options.max_connections = 2;
  StartedServer s(echo_handler(), options);
  RawSocket first(s.port), second(s.port);
  first.send(kGet);
  second.send(kGet);
  CHECK(first.read_response().status == 200);
  CHECK(second.read_response().status == 200);

  RawSocket other(s.port);
  other.send(kGet);
  const auto refused = other.read_response();
  CHECK(refused.status == 503);
  CHECK(refused.headers.at("retry-after") == "1");
  CHECK(refused.headers.at("connection") == "close");
  CHECK(json::parse(refused.body)["code"] == "SERVER_BUSY");
  CHECK(other.wait_closed());

  RawSocket stop(s.port);
  stop.send(kStop);
  const auto answered = stop.read_response();
  CHECK(answered.status == 200);
  CHECK(answered.headers.at("connection") == "close");  // one answer: the slot beyond the limit is freed
  CHECK(stop.wait_closed());

  first.send(kGet);  // the admitted ones are untouched
  CHECK(first.read_response().status == 200);
}

TEST_CASE("one client address cannot take more than max_connections_per_address") {
  auto options = priority_options();
  options.max_connections_per_address = 3;
  StartedServer s(echo_handler(), options);
  std::vector<std::unique_ptr<RawSocket>> held;
  for (int i = 0; i < 3; ++i) {
    held.push_back(std::make_unique<RawSocket>(s.port));
    held.back()->send(kGet);
    CHECK(held.back()->read_response().status == 200);
  }
  RawSocket fourth(s.port);
  fourth.send(kGet);
  CHECK(fourth.read_response().status == 503);  // far below max_connections: the per-address cap
  RawSocket stop(s.port);
  stop.send(kStop);
  CHECK(stop.read_response().status == 200);

  held.pop_back();                     // one ends: its address may connect again
  for (int attempt = 0;; ++attempt) {  // the close reaches the server asynchronously: retry a 503 until it has
    RawSocket again(s.port);
    again.send(kGet);
    const auto status = again.read_response().status;
    if (status == 200 || attempt == 200) {
      CHECK(status == 200);
      break;
    }
  }
}

TEST_CASE("a slow-loris at the limit fills the busy lane, which evicts its oldest, so a stop still gets in") {
  auto options = priority_options();
  options.max_connections = 4;
  options.busy_lane = 3;
  StartedServer s(echo_handler(), options);
  std::vector<std::unique_ptr<RawSocket>> loris;
  for (int i = 0; i < 4; ++i) {  // at the limit, each with a request that never ends
    loris.push_back(std::make_unique<RawSocket>(s.port));
    loris.back()->send("GET /x HTTP/1.1\r\nHost: h\r\n");
  }
  std::vector<std::unique_ptr<RawSocket>> lane;
  for (int i = 0; i < 6; ++i) {  // then six more that send nothing: only the last three stay in the lane
    lane.push_back(std::make_unique<RawSocket>(s.port));
  }
  for (int i = 0; i < 3; ++i) CHECK(lane[i]->wait_closed());
  RawSocket stop(s.port);
  stop.send(kStop);
  CHECK(stop.read_response().status == 200);
  CHECK(lane[3]->wait_closed());  // the stop took the oldest waiter's place
}

TEST_CASE("without priority, connections beyond the per-address cap are closed at once") {
  http::ServerOptions options;
  options.max_connections_per_address = 1;
  StartedServer s(echo_handler(), options);
  RawSocket first(s.port);
  first.send(kGet);
  CHECK(first.read_response().status == 200);
  RawSocket second(s.port);
  std::string received;
  CHECK(second.wait_closed(5000ms, &received));
  CHECK(received.empty());
}

TEST_CASE("refused before the handler: lower-case methods, HTTP/1.1 without Host, a transfer coding besides chunked") {
  int calls = 0;
  StartedServer s(
      [&calls](http::Request&& request, http::Respond respond) {
        ++calls;
        respond(echo_response(request));
      },
      priority_options());
  auto refused = [&](const std::string& request, int status, const std::string& code, const std::string& says) {
    RawSocket raw(s.port);
    raw.send(request);
    const auto answer = raw.read_response();
    CHECK(answer.status == status);
    const auto body = json::parse(answer.body);
    CHECK(body["code"] == code);
    CHECK(body["error"].get<std::string>().find(says) != std::string::npos);
    CHECK(raw.wait_closed());
  };
  refused("get /x HTTP/1.1\r\nHost: h\r\n\r\n", 400, "BAD_REQUEST", "'get' is not upper case");
  refused("Post /stop HTTP/1.1\r\nHost: h\r\nContent-Length: 0\r\n\r\n", 400, "BAD_REQUEST", "not upper case");
  refused("GET /x HTTP/1.1\r\n\r\n", 400, "BAD_REQUEST", "Host");
  refused("POST /x HTTP/1.1\r\nHost: h\r\nTransfer-Encoding: gzip, chunked\r\n\r\n5\r\nhello\r\n0\r\n\r\n", 501,
          "NOT_IMPLEMENTED", "gzip,chunked");
  refused("POST /x HTTP/1.1\r\nHost: h\r\nTransfer-Encoding: gzip\r\nTransfer-Encoding: chunked\r\n\r\n0\r\n\r\n", 501,
          "NOT_IMPLEMENTED", "only chunked");
  CHECK(calls == 0);

  RawSocket old(s.port);  // HTTP/1.0 needs no Host; chunked alone is fine
  old.send("GET /old HTTP/1.0\r\n\r\n");
  CHECK(old.read_response().status == 200);
  RawSocket chunked(s.port);
  chunked.send("POST /c HTTP/1.1\r\nHost: h\r\nTransfer-Encoding: Chunked\r\n\r\n5\r\nhello\r\n0\r\n\r\n");
  CHECK(json::parse(chunked.read_response().body)["body"] == "hello");
}

TEST_CASE("a WebSocket version other than 13 gets 426 as JSON naming the version spoken") {
  auto options = priority_options();
  bool taken = false;
  options.upgrade = [&taken](const http::Request&) {
    http::UpgradeVerdict verdict;
    verdict.take = [&taken](http::Upgraded&&) { taken = true; };
    return verdict;
  };
  StartedServer s(echo_handler(), options);
  RawSocket raw(s.port);
  raw.send(
      "GET /ws HTTP/1.1\r\nHost: h\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 8\r\n\r\n");
  const auto answer = raw.read_response();
  CHECK(answer.status == 426);
  CHECK(answer.headers.at("sec-websocket-version") == "13");
  CHECK(answer.headers.at("content-type") == "application/json");
  CHECK(json::parse(answer.body)["code"] == "UPGRADE_REQUIRED");
  CHECK_FALSE(taken);
}

TEST_CASE("the screen sees every request first: a refused one (a stop, an upgrade) reaches neither handler nor hook") {
  auto options = priority_options();
  std::atomic<int> screened = 0, taken = 0, handled = 0;
  options.screen = [&screened](const http::Request& request) -> std::optional<http::Response> {
    ++screened;
    if (!request.header("origin")) return std::nullopt;
    return http::error_response(403, "ORIGIN_NOT_ALLOWED", "not from here");
  };
  options.upgrade = [&taken](const http::Request&) {
    http::UpgradeVerdict verdict;
    verdict.take = [&taken](http::Upgraded&&) { ++taken; };
    return verdict;
  };
  StartedServer s(
      [&handled](http::Request&& request, http::Respond respond) {
        ++handled;
        respond(echo_response(request));
      },
      options);
  RawSocket stop(s.port);  // a priority request, on the accept loop
  stop.send("POST /stop HTTP/1.1\r\nHost: h\r\nOrigin: http://elsewhere\r\nContent-Length: 0\r\n\r\n");
  auto answer = stop.read_response();
  CHECK(answer.status == 403);
  CHECK(json::parse(answer.body)["code"] == "ORIGIN_NOT_ALLOWED");
  CHECK(stop.wait_closed());
  RawSocket ws(s.port);
  ws.send(
      "GET /ws HTTP/1.1\r\nHost: h\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nOrigin: http://elsewhere\r\n"
      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n");
  CHECK(ws.read_response().status == 403);
  RawSocket plain(s.port);  // a worker's request without Origin goes on
  plain.send(kGet);
  CHECK(plain.read_response().status == 200);
  CHECK(screened == 3);
  CHECK(taken == 0);
  CHECK(handled == 1);
}

TEST_CASE("the busy lane evicts connections that sent nothing before one whose request is on its way") {
  auto options = priority_options();
  options.max_connections = 1;
  options.busy_lane = 3;
  StartedServer s(echo_handler(), options);
  RawSocket held(s.port);
  held.send(kGet);
  CHECK(held.read_response().status == 200);
  RawSocket stop(s.port);  // in the lane, its request half sent
  stop.send("POST /stop HTTP/1.1\r\nHost: h\r\n");
  std::vector<std::unique_ptr<RawSocket>> silent;
  for (int i = 0; i < 6; ++i) silent.push_back(std::make_unique<RawSocket>(s.port));  // newer, but silent
  for (int i = 0; i < 4; ++i) CHECK(silent[i]->wait_closed());                        // they went, oldest first
  stop.send("Content-Length: 0\r\n\r\n");
  CHECK(stop.read_response().status == 200);
}
