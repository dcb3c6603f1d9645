#include <doctest/doctest.h>

#include <future>

#include "kernel/audit/audit_log.hpp"
#include "libs/base/json_body.hpp"
#include "libs/base/worker_thread.hpp"

using namespace rcand;
using namespace rcand::kernel;

TEST_CASE("audit log: newest first, outcome filled in after dispatch, bounded") {
  AuditLog audit(3);
  const auto a = audit.record({0, "alice", "rcan://x", "m1", "POST /api/action move", 1, "pending", {}});
  const auto b = audit.record({0, "bob", "rcan://x", "m2", "POST /api/stop", 2, "pending", {}});
  audit.finish(a, "blocked", "e-stop active");
  audit.finish(b, "ok");
  auto doc = audit.to_json(10);
  REQUIRE(doc["entries"].size() == 2);
  CHECK(doc["entries"][0]["principal"] == "bob");
  CHECK(doc["entries"][0]["outcome"] == "ok");
  CHECK(doc["entries"][1]["outcome"] == "blocked");
  CHECK(doc["entries"][1]["detail"] == "e-stop active");
  for (auto key : {"principal", "ruri", "timestamp_ms", "message_id", "event", "outcome"}) CHECK(doc["entries"][0].contains(key));
  for (int i = 0; i < 5; ++i) audit.record({0, "c", "r", "m", "e", 3, "pending", {}});
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
  const auto cancelled = worker.schedule(std::chrono::milliseconds(1), [seen] { seen->push_back(99); });
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
