// Plugin status() calls on their own threads: concurrent readers of one call share it instead of each waiting.
#include <doctest/doctest.h>

#include <atomic>
#include <chrono>
#include <future>

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
