// Streamed answers (Response::stream, libs/http/response_stream.hpp) and the SDK StreamWriter on top of them
// (libs/http/stream_writer.hpp): the header without Content-Length, parts in order, at most one pending part per
// client (a newer one replaces it and counts a drop), a producer that never waits for a client that does not read, the
// stall timeout, and the client leaving.
#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include <condition_variable>
#include <mutex>
#include <thread>

#include "http_test_util.hpp"
#include "libs/http/response_stream.hpp"
#include "libs/http/stream_writer.hpp"
#include "raw_socket.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

// Each request is answered by a stream writer the test then drives.
class Writers {
 public:
  http::Handler handler() {
    return [this](http::Request&&, http::Respond respond) {
      auto writer = http::make_stream_writer([respond](http::Response response) {
        respond(std::move(response));
        return true;
      });
      std::lock_guard lock(mutex_);
      writers_.push_back(std::move(writer));
      ready_.notify_all();
    };
  }
  std::shared_ptr<rcand::sdk::StreamWriter> next(std::chrono::milliseconds limit = 5000ms) {
    std::unique_lock lock(mutex_);
    if (!ready_.wait_for(lock, limit, [&] { return taken_ < writers_.size(); })) return nullptr;
    return std::move(writers_[taken_++]);  // the test holds the only reference
  }

 private:
  std::mutex mutex_;
  std::condition_variable ready_;
  std::vector<std::shared_ptr<rcand::sdk::StreamWriter>> writers_;
  std::size_t taken_ = 0;
};

rcand::sdk::SharedBytes bytes(std::string text) { return std::make_shared<const std::string>(std::move(text)); }

// Bounded: a writer's closed() has no event to wait on from outside.
bool eventually_closed(const rcand::sdk::StreamWriter& writer, std::chrono::milliseconds limit) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  while (!writer.closed()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(2ms);
  }
  return true;
}

}  // namespace

TEST_CASE("stream: a multipart answer is the header, then each part framed, then the close") {
  Writers writers;
  StartedServer s(writers.handler());
  RawSocket client(s.port);
  client.send("GET /stream HTTP/1.1\r\nHost: x\r\n\r\n");
  auto writer = writers.next();
  REQUIRE(writer);
  REQUIRE(writer->start(200, "multipart/x-mixed-replace", {{"X-Extra", "1"}}));
  CHECK_FALSE(writer->start(200, "text/plain", {}));  // one answer only
  CHECK(writer->push({bytes("frame-one"), "image/jpeg", {{"X-Frame", "1"}, {"Bad\r\nName", "x"}}}));
  std::string received;
  // The first part is written before the second is pushed: nothing replaced it.
  client.wait_closed(300ms, &received);
  CHECK(writer->push({bytes("frame-two"), "image/jpeg", {}}));
  writer->end();
  CHECK_FALSE(writer->push({bytes("late"), "image/jpeg", {}}));
  REQUIRE(client.wait_closed(5000ms, &received));
  CHECK(received.starts_with("HTTP/1.1 200 OK\r\n"));
  CHECK(received.find("Content-Type: multipart/x-mixed-replace; boundary=rcandframe\r\n") != std::string::npos);
  CHECK(received.find("Content-Length") == received.find("Content-Length: 9\r\n"));  // only the parts have one
  CHECK(received.find("Connection: close\r\n") != std::string::npos);
  CHECK(received.find("X-Extra: 1\r\n") != std::string::npos);
  const auto one =
      received.find("--rcandframe\r\nContent-Type: image/jpeg\r\nContent-Length: 9\r\nX-Frame: 1\r\n\r\nframe-one\r\n");
  const auto two = received.find("--rcandframe\r\nContent-Type: image/jpeg\r\nContent-Length: 9\r\n\r\nframe-two\r\n");
  CHECK(one != std::string::npos);
  CHECK(two != std::string::npos);
  CHECK(one < two);
  CHECK(received.find("Bad") == std::string::npos);  // a header that would split the part is dropped
  CHECK(received.find("late") == std::string::npos);
  CHECK(writer->counters().sent == 2);
  CHECK(writer->counters().dropped == 0);
  CHECK(writer->counters().bytes == 18);
}

TEST_CASE("stream: a client that never reads holds one pending part, never blocks the producer, and is cut off") {
  Writers writers;
  http::ServerOptions options;
  options.stream_stall_timeout = 300ms;
  StartedServer s(writers.handler(), options);
  RawSocket stalled(s.port), reader(s.port);
  stalled.send("GET /stream HTTP/1.1\r\nHost: x\r\n\r\n");
  auto slow = writers.next();
  reader.send("GET /stream HTTP/1.1\r\nHost: x\r\n\r\n");
  auto fast = writers.next();
  REQUIRE(slow);
  REQUIRE(fast);
  REQUIRE(slow->start(200, "multipart/x-mixed-replace", {}));
  REQUIRE(fast->start(200, "multipart/x-mixed-replace", {}));

  // 1 MiB frames, shared, pushed as a camera would until the server gives up on the stalled client: its socket
  // buffers fill after a few, then each push replaces its one pending part. A push never waits for it.
  const auto frame = bytes(std::string(1 << 20, 'x'));
  const auto started = std::chrono::steady_clock::now();
  auto slowest_push = std::chrono::steady_clock::duration::zero();
  int pushes = 0;
  while (!slow->closed() && std::chrono::steady_clock::now() - started < 5s) {
    const auto before = std::chrono::steady_clock::now();
    slow->push({frame, "image/jpeg", {}});
    slowest_push = std::max(slowest_push, std::chrono::steady_clock::now() - before);
    ++pushes;
    if (pushes == 100) {  // meanwhile the reading client gets its parts
      fast->push({bytes("hello"), "image/jpeg", {}});
      fast->end();
    }
    std::this_thread::sleep_for(1ms);  // a 1 kHz camera
  }
  // No progress for stream_stall_timeout: the server closed the stalled one, and its producer sees it.
  REQUIRE(slow->closed());
  CHECK(std::chrono::steady_clock::now() - started < 3s);
  CHECK(slowest_push < 50ms);
  CHECK(slow->counters().dropped > slow->counters().sent);
  std::string received;
  REQUIRE(reader.wait_closed(5000ms, &received));
  CHECK(received.find("\r\n\r\nhello\r\n") != std::string::npos);
  CHECK_FALSE(slow->push({frame, "image/jpeg", {}}));
}

TEST_CASE("stream: the client leaving closes the stream for its producer") {
  Writers writers;
  StartedServer s(writers.handler());
  RawSocket client(s.port);
  client.send("GET /stream HTTP/1.1\r\nHost: x\r\n\r\n");
  auto writer = writers.next();
  REQUIRE(writer);
  REQUIRE(writer->start(200, "multipart/x-mixed-replace", {}));
  REQUIRE(writer->push({bytes("one"), "image/jpeg", {}}));
  client.close();
  CHECK(eventually_closed(*writer, 3000ms));
}

TEST_CASE("stream: whole bodies, JSON answers and dropped writers") {
  Writers writers;
  StartedServer s(writers.handler());
  SUBCASE("start then send: one body with its Content-Length, kept alive") {
    RawSocket client(s.port);
    client.send("GET /snapshot HTTP/1.1\r\nHost: x\r\n\r\n");
    auto writer = writers.next();
    REQUIRE(writer);
    CHECK_FALSE(writer->push({bytes("x"), "image/jpeg", {}}));  // not a multipart answer
    REQUIRE(writer->start(200, "image/jpeg", {{"X-Timestamp-Us", "42"}}));
    REQUIRE(writer->send(bytes("JPEGDATA")));
    const auto response = client.read_response();
    CHECK(response.status == 200);
    CHECK(response.headers.at("content-type") == "image/jpeg");
    CHECK(response.headers.at("content-length") == "8");
    CHECK(response.headers.at("x-timestamp-us") == "42");
    CHECK(response.body == "JPEGDATA");
    CHECK(writer->closed());
    CHECK(writer->counters().sent == 1);
  }
  SUBCASE("respond: the error shape, whatever the plugin gave") {
    RawSocket client(s.port);
    client.send("GET /stream HTTP/1.1\r\nHost: x\r\n\r\n");
    auto writer = writers.next();
    REQUIRE(writer);
    REQUIRE(writer->respond({503, json{{"limit", 2}}}, {{"Retry-After", "5"}}));
    CHECK_FALSE(writer->start(200, "multipart/x-mixed-replace", {}));
    const auto response = client.read_response();
    CHECK(response.status == 503);
    CHECK(response.headers.at("retry-after") == "5");
    const auto body = json::parse(response.body);
    CHECK(body["limit"] == 2);
    CHECK(body["status"] == 503);
    CHECK(body["code"] == "INTERNAL");
  }
  SUBCASE("a writer dropped without an answer answers 500") {
    RawSocket client(s.port);
    client.send("GET /stream HTTP/1.1\r\nHost: x\r\n\r\n");
    auto writer = writers.next();
    REQUIRE(writer);
    writer.reset();
    CHECK(client.read_response().status == 500);
  }
  SUBCASE("an answer refused by the host (the request timed out) reads as closed") {
    auto writer = http::make_stream_writer([](http::Response) { return false; });
    CHECK_FALSE(writer->start(200, "multipart/x-mixed-replace", {}));
    CHECK(writer->closed());
  }
}

TEST_CASE("stream: ResponseStream keeps one pending part and wakes its session once") {
  http::ResponseStream stream;
  int wakes = 0;
  stream.attach([&] { ++wakes; });
  http::ResponseStream::Part part;
  CHECK(stream.next(part) == http::ResponseStream::Next::Wait);  // arms the wake
  CHECK(stream.push({"h1", bytes("a"), "t"}));
  CHECK(stream.push({"h2", bytes("b"), "t"}));
  CHECK(wakes == 1);
  CHECK(stream.counters().dropped == 1);
  REQUIRE(stream.next(part) == http::ResponseStream::Next::Part);
  CHECK(part.head == "h2");
  CHECK(part.size() == 4);
  stream.written(1);
  CHECK(stream.counters().sent == 1);
  stream.end();
  CHECK(stream.next(part) == http::ResponseStream::Next::End);
  CHECK_FALSE(stream.push({"h3", bytes("c"), "t"}));
  stream.close();
  CHECK(stream.closed());
}

TEST_CASE("stream: a stream offered no part for stream_stall_timeout ends cleanly, and its producer sees it closed") {
  // Issue 28 #8: a viewer at ?fps=0.001 is offered one frame and then nothing; it must not hold its place for ever.
  Writers writers;
  http::ServerOptions options;
  CHECK(options.stream_stall_timeout == 10s);  // what rcand serves with (the 10 s); shortened here for the test
  options.stream_stall_timeout = 300ms;
  StartedServer s(writers.handler(), options);
  RawSocket idle(s.port), fed(s.port);
  idle.send("GET /stream HTTP/1.1\r\nHost: x\r\n\r\n");
  auto starved = writers.next();
  fed.send("GET /stream HTTP/1.1\r\nHost: x\r\n\r\n");
  auto busy = writers.next();
  REQUIRE(starved);
  REQUIRE(busy);
  REQUIRE(starved->start(200, "multipart/x-mixed-replace", {}));
  REQUIRE(busy->start(200, "multipart/x-mixed-replace", {}));
  REQUIRE(starved->push({bytes("only-frame"), "image/jpeg", {}}));
  const auto started = std::chrono::steady_clock::now();
  // The fed stream gets a part every 100 ms (well within the timeout) for a second: it is never cut.
  while (std::chrono::steady_clock::now() - started < 1s) {
    REQUIRE(busy->push({bytes("frame"), "image/jpeg", {}}));
    std::this_thread::sleep_for(100ms);  // a 10 fps camera
  }
  CHECK(eventually_closed(*starved, 3000ms));  // was never: a stream with nothing to send stayed open
  std::string received;
  REQUIRE(idle.wait_closed(3000ms, &received));  // the connection ends (FIN), after the whole part it had
  CHECK(received.find("\r\n\r\nonly-frame\r\n") != std::string::npos);
  CHECK_FALSE(busy->closed());
  busy->end();
  REQUIRE(fed.wait_closed(3000ms, &received));
  CHECK(received.find("frame") != std::string::npos);
}

TEST_CASE("stream: what a stream holds (its slot) is let go when the stream closes") {
  http::ResponseStream stream;
  auto slot = std::make_shared<int>(1);
  std::weak_ptr<int> watch = slot;
  stream.hold(std::move(slot));
  CHECK_FALSE(watch.expired());
  stream.close();
  CHECK(watch.expired());
  stream.hold(std::make_shared<int>(2));  // after the close: not kept
}
