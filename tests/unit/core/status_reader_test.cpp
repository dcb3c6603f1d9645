// Plugin status() calls on their own threads: concurrent readers of one call share it instead of each waiting; a late
// call is not a hung one.
#include <doctest/doctest.h>

#include <atomic>
#include <chrono>
#include <future>

#include "eventually.hpp"
#include "kernel/plugins/status_reader.hpp"

using namespace rcand;
using namespace rcand::kernel;
using namespace std::chrono_literals;
using nlohmann::json;

TEST_CASE("a reader does not start or wait for a status() call that another reader is already waiting for") {
  std::atomic<int> calls{0};
  std::promise<void> entered, release;
  const auto released = release.get_future().share();
  InstanceHealth health;
  StatusReader reader({{"plugin test capability slow",
                        [&] {
                          const int n = ++calls;
                          if (n == 1) {  // the first call blocks until the test lets it go
                            entered.set_value();
                            released.wait();
                          }
                          return json{{"call", n}};
                        },
                        &health}});

  auto first = std::async(std::launch::async, [&] { return reader.read(0); });
  entered.get_future().wait();
  CHECK_FALSE(reader.read(0).has_value());  // at once: the call in flight has no value yet, and none came before
  release.set_value();
  first.get();
  REQUIRE(reader.quiesce(5s));
  CHECK(calls == 1);  // the second reader started no call of its own
  CHECK_FALSE(health.failed());

  const auto fresh = reader.read(0);  // nothing in flight any more: a new call
  REQUIRE(fresh.has_value());
  CHECK((*fresh)["call"] == 2);
}

// Regression (CI, stop 35): on a loaded machine an arm's status() thread waited over 250 ms for a core, and the
// capability was failed for good; the dashboard showed a healthy arm as failed.
TEST_CASE("a status() that answers late gives its last value and is not failed; the next read gets the new one") {
  std::atomic<int> calls{0};
  std::promise<void> release;
  const auto released = release.get_future().share();
  InstanceHealth health;
  StatusReader reader({{"plugin test capability late",
                        [&] {
                          const int n = ++calls;
                          if (n == 2) released.wait();  // the second call is late
                          return json{{"call", n}};
                        },
                        &health}});
  REQUIRE(reader.read(0).has_value());
  const auto late = reader.read(0);  // waits kStatusDeadline, then answers the first call's value
  REQUIRE(late.has_value());
  CHECK((*late)["call"] == 1);
  CHECK_FALSE(health.failed());
  release.set_value();
  REQUIRE(reader.quiesce(5s));
  const auto next = reader.read(0);
  REQUIRE(next.has_value());
  CHECK((*next)["call"] == 3);
  CHECK_FALSE(health.failed());
}

TEST_CASE("a status() still running kHungAfter after it was asked is failed for good and never asked again") {
  std::atomic<int> calls{0};
  std::promise<void> release;
  const auto released = release.get_future().share();
  InstanceHealth health;
  StatusReader reader({{"plugin test capability hung",
                        [&] {
                          ++calls;
                          released.wait();
                          return json{{"answered", true}};
                        },
                        &health}});
  CHECK_FALSE(reader.read(0).has_value());
  CHECK_FALSE(health.failed());  // late, not yet hung
  CHECK(rcand::test::eventually([&] { return !reader.read(0).has_value() && health.failed(); }, 10s, 50ms));
  CHECK(health.reason() == "status() did not return within 2000 ms (it must not block)");
  release.set_value();
  REQUIRE(reader.quiesce(5s));
  CHECK_FALSE(reader.read(0).has_value());
  CHECK(calls == 1);
}
