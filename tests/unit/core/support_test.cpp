#include <doctest/doctest.h>

#include <pthread.h>
#include <boost/asio/post.hpp>

#include <future>
#include <thread>

#include "kernel/audit/audit_log.hpp"
#include "libs/base/json_body.hpp"
#include "libs/base/worker_thread.hpp"

using namespace rcand;
using namespace rcand::kernel;

TEST_CASE("audit log: newest first, outcome filled in after dispatch, bounded") {
  AuditLog audit(3);
  const auto a = audit.record({0, "alice", "rcan://x", "m1", "POST /api/action move", 1, "pending", {}, nullptr});
  const auto b = audit.record({0, "bob", "rcan://x", "m2", "POST /api/stop", 2, "pending", {}, nullptr});
  audit.finish(a, "blocked", "e-stop active");
  audit.finish(b, "ok");
  auto doc = audit.to_json(10);
  REQUIRE(doc["entries"].size() == 2);
  CHECK(doc["entries"][0]["principal"] == "bob");
  CHECK(doc["entries"][0]["outcome"] == "ok");
  CHECK(doc["entries"][1]["outcome"] == "blocked");
  CHECK(doc["entries"][1]["detail"] == "e-stop active");
  for (auto key : {"principal", "ruri", "timestamp_ms", "message_id", "event", "outcome"}) CHECK(doc["entries"][0].contains(key));
  for (int i = 0; i < 5; ++i) audit.record({0, "c", "r", "m", "e", 3, "pending", {}, nullptr});
  CHECK(audit.to_json(10)["entries"].size() == 3);
  CHECK(audit.total() == 7);
  audit.finish(a, "ok");  // rotated out: ignored, no crash
}

TEST_CASE("json bodies: empty, valid, invalid and too deep") {
  CHECK(parse_json_body("").value.is_null());
  CHECK(parse_json_body("  \n").error.empty());
  CHECK(parse_json_body("{\"a\":1}").value["a"] == 1);
  CHECK(parse_json_body("{\"a\":").error.find("not valid JSON") != std::string::npos);
  std::string deep(100000, '[');
  CHECK(parse_json_body(deep).error.find("deeper") != std::string::npos);
  std::string ok_depth = std::string(60, '[') + std::string(60, ']');
  CHECK(parse_json_body(ok_depth).error.empty());
}

TEST_CASE("worker: tasks in order, timers fire, cancelled timers never run, exceptions reported") {
  std::promise<std::string> error;
  WorkerThread worker("test", [&](const std::string& why) { error.set_value(why); });
  auto seen = std::make_shared<std::vector<int>>();
  worker.post([seen] { seen->push_back(1); });
  worker.post([seen] { seen->push_back(2); });
  std::promise<void> fired;
  // Due in an hour: cancelled long before, however loaded the machine (at 1 ms a sanitizer run under load once fired
  // it before the cancel).
  const auto cancelled = worker.schedule(std::chrono::hours(1), [seen] { seen->push_back(99); });
  CHECK(worker.cancel(cancelled));
  CHECK_FALSE(worker.cancel(cancelled));
  worker.schedule(std::chrono::milliseconds(2), [&, seen] {
    seen->push_back(3);
    fired.set_value();
  });
  fired.get_future().wait();
  worker.post([] { throw std::runtime_error("boom"); });
  CHECK(error.get_future().get() == "boom");
  std::promise<void> drained;
  worker.post([&] { drained.set_value(); });
  drained.get_future().wait();
  CHECK(*seen == std::vector<int>{1, 2, 3});
  worker.join();
  worker.join();  // idempotent
}

TEST_CASE("worker: a named thread that survives a throwing I/O handler, and the three ways to end") {
  std::promise<std::string> error;
  WorkerThread worker("test.executor.long-name", [&](const std::string& why) { error.set_value(why); });
  std::promise<std::string> name;
  worker.post([&] {
    char text[16] = {};
    pthread_getname_np(pthread_self(), text, sizeof text);
    name.set_value(text);
  });
  CHECK(name.get_future().get() == "test.executor.l");  // Linux keeps 15 characters
  // A handler given straight to the io_context (as a socket's completion is) throws: logged, reported, loop goes on.
  boost::asio::post(worker.context(), [] { throw std::runtime_error("bad datagram"); });
  CHECK(error.get_future().get() == "bad datagram");
  std::promise<void> alive;
  worker.post([&] { alive.set_value(); });
  alive.get_future().wait();

  // stop_after_queued(): what was queued before runs; stop(): nothing queued runs any more.
  auto ran = std::make_shared<std::vector<int>>();
  {
    WorkerThread transport("test.transport", nullptr);
    std::promise<void> release;
    auto held = release.get_future().share();
    transport.post([held] { held.wait(); });
    transport.post([ran] { ran->push_back(1); });
    std::thread releaser([&release] {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      release.set_value();
    });
    transport.stop_after_queued();
    releaser.join();
    CHECK(*ran == std::vector<int>{1});
    transport.post([ran] { ran->push_back(2); });  // after the end: never runs
  }
  CHECK(*ran == std::vector<int>{1});
  {
    WorkerThread fan_out("test.fanout", nullptr);
    std::promise<void> started, release;
    auto held = release.get_future().share();
    fan_out.post([&started, held] {
      started.set_value();
      held.wait();
    });
    fan_out.post([ran] { ran->push_back(3); });
    started.get_future().wait();
    std::thread releaser([&release] {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      release.set_value();
    });
    fan_out.stop();  // the running task finishes; the queued one is abandoned
    releaser.join();
    fan_out.join();  // already ended: a no-op
  }
  CHECK(*ran == std::vector<int>{1});
}
