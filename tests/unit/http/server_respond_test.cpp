#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include <condition_variable>
#include <deque>
#include <mutex>
#include <memory>
#include <stdexcept>
#include <thread>

#include "http_test_util.hpp"
#include "libs/http/client.hpp"
#include "raw_socket.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

// Requests the handler parked for the test to answer later, from whichever thread it likes.
class Parked {
 public:
  struct Entry {
    http::Request request;
    http::Respond respond;
  };

  http::Handler handler() {
    return [this](http::Request&& request, http::Respond respond) {
      std::lock_guard lock(mutex_);
      entries_.push_back({std::move(request), std::move(respond)});
      ready_.notify_all();
    };
  }

  // Waits for the next parked request (the limit only turns a bug into a failure instead of a hang).
  std::unique_ptr<Entry> pop(std::chrono::milliseconds limit = 5000ms) {
    std::unique_lock lock(mutex_);
    if (!ready_.wait_for(lock, limit, [&] { return !entries_.empty(); })) return nullptr;
    auto entry = std::make_unique<Entry>(std::move(entries_.front()));
    entries_.pop_front();
    return entry;
  }

 private:
  std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<Entry> entries_;
};

http::Response text(std::string body) { return http::Response{200, "text/plain", std::move(body), {}}; }

}  // namespace

TEST_CASE("a handler may answer later from another thread") {
  Parked parked;
  StartedServer s(parked.handler());
  std::thread worker([&] {
    if (auto entry = parked.pop()) entry->respond(text("late:" + entry->request.path));
  });
  auto response = http::request("127.0.0.1", s.port, "GET", "/slow");
  worker.join();
  CHECK(response.status == 200);
  CHECK(response.body == "late:/slow");
}

TEST_CASE("a pending answer holds up no other connection, even with one I/O thread") {
  Parked parked;
  http::ServerOptions options;
  options.io_threads = 1;
  auto park = parked.handler();
  StartedServer s(
      [&](http::Request&& request, http::Respond respond) {
        if (request.path == "/slow") return park(std::move(request), std::move(respond));
        respond(text("fast"));
      },
      options);
  RawSocket slow(s.port);
  slow.send("GET /slow HTTP/1.1\r\nHost: h\r\n\r\n");
  auto entry = parked.pop();
  REQUIRE(entry);
  CHECK(http::request("127.0.0.1", s.port, "POST", "/api/estop").body == "fast");
  entry->respond(text("slow"));
  CHECK(slow.read_response().body == "slow");
}

TEST_CASE("a second Respond is ignored") {
  StartedServer s([](http::Request&&, http::Respond respond) {
    respond(text("first"));
    respond(text("second"));
  });
  RawSocket raw(s.port);
  raw.send("GET /1 HTTP/1.1\r\nHost: h\r\n\r\n");
  CHECK(raw.read_response().body == "first");
  // Had "second" been written it would sit on the wire ahead of this answer.
  raw.send("GET /2 HTTP/1.1\r\nHost: h\r\n\r\n");
  CHECK(raw.read_response().body == "first");
}

TEST_CASE("racing Responds from two threads give exactly one answer") {
  Parked parked;
  StartedServer s(parked.handler());
  http::Client client("127.0.0.1", s.port);
  for (int round = 0; round < 20; ++round) {
    std::thread answerer([&] {
      auto entry = parked.pop();
      if (!entry) return;
      std::thread other([respond = entry->respond] { respond(text("b")); });
      entry->respond(text("a"));
      other.join();
    });
    auto response = client.request("GET", "/race");
    answerer.join();
    CHECK((response.body == "a" || response.body == "b"));
  }
  CHECK(s.server->connection_count() == 1);  // every answer kept the connection in step
}

TEST_CASE("Respond after the client disconnected is harmless") {
  Parked parked;
  StartedServer s(parked.handler());
  {
    RawSocket raw(s.port);
    raw.send("GET /gone HTTP/1.1\r\nHost: h\r\n\r\n");
    auto entry = parked.pop();
    REQUIRE(entry);
    raw.close();
    entry->respond(text("nobody listens"));
    entry->respond(text("still nobody"));
  }
  std::thread worker([&] {
    if (auto entry = parked.pop()) entry->respond(text("alive"));
  });
  auto response = http::request("127.0.0.1", s.port, "GET", "/next");
  worker.join();
  CHECK(response.body == "alive");
}

TEST_CASE("Respond after the server was stopped and destroyed is harmless") {
  Parked parked;
  auto s = std::make_unique<StartedServer>(parked.handler());
  RawSocket raw(s->port);
  raw.send("GET /held HTTP/1.1\r\nHost: h\r\n\r\n");
  auto entry = parked.pop();
  REQUIRE(entry);
  s.reset();  // stop() closes the connection even though its request is unanswered
  CHECK(raw.wait_closed());
  entry->respond(text("too late"));
  entry.reset();  // the last reference to the server's loops goes here
}

TEST_CASE("a dropped Respond answers 500") {
  SUBCASE("dropped inline") {
    StartedServer s([](http::Request&&, http::Respond) {});
    auto response = http::request("127.0.0.1", s.port, "GET", "/");
    CHECK(response.status == 500);
    CHECK(json::parse(response.body)["code"] == "INTERNAL");
  }
  SUBCASE("dropped later on another thread") {
    Parked parked;
    StartedServer s(parked.handler());
    std::thread dropper([&] { parked.pop(); });
    auto response = http::request("127.0.0.1", s.port, "GET", "/");
    dropper.join();
    CHECK(response.status == 500);
  }
}

TEST_CASE("a throwing handler answers 500 and the connection stays usable") {
  StartedServer s([](http::Request&& request, http::Respond respond) {
    if (request.path == "/answered-then-throws") {
      respond(text("kept"));
      throw std::runtime_error("after answering");
    }
    if (request.path == "/throws") throw std::runtime_error("boom");
    respond(text("fine"));
  });
  http::Client client("127.0.0.1", s.port);
  auto thrown = client.request("GET", "/throws");
  CHECK(thrown.status == 500);
  CHECK(json::parse(thrown.body) == json{{"error", "internal error"}, {"code", "INTERNAL"}, {"status", 500}});
  CHECK(client.request("GET", "/answered-then-throws").body == "kept");
  CHECK(client.request("GET", "/ok").body == "fine");
  CHECK(s.server->connection_count() == 1);
}
