// The telemetry frame from a status document: every MUST field of docs/protocol.md §7.10 present, nulls where rcand
// has no source, states and pose carried over, obstacles from an ObstacleSource.
#include <doctest/doctest.h>

#include <limits>

#include "services/telemetry/telemetry_frame.hpp"

using namespace rcand::services::telemetry;
using nlohmann::json;

namespace {

class FixedObstacles final : public rcand::sdk::ObstacleSource {
 public:
  explicit FixedObstacles(rcand::sdk::ObstacleReading reading) : reading_(reading) {}
  rcand::sdk::ObstacleReading obstacles() const noexcept override { return reading_; }

 private:
  rcand::sdk::ObstacleReading reading_;
};

const json kStatus = {{"state", "running"},
                      {"estopped", false},
                      {"uptime_s", 42},
                      {"nav_running", true},
                      {"pose", {{"x_m", 1.5}, {"y_m", -0.5}, {"heading_deg", 90.0}}},
                      {"capabilities",
                       {{"teleop", {{"plugin", "t"}, {"state", "ok"}, {"status", {{"moving", false}}}}},
                        {"nav", {{"plugin", "n"}, {"state", "ok"}, {"stale", true}, {"age_ms", 2500}}},
                        {"power", {{"plugin", "p"}, {"state", "ok"}, {"status", {{"battery_v", 12.4}}}}}}},
                      {"drivers", {{{"id", "drive0"}, {"state", "ok"}}, {{"id", "arm0"}, {"state", "failed"}, {"reason", "x"}}}}};

}  // namespace

TEST_CASE("telemetry frame: MUST fields, honest nulls, rcand's additions") {
  FrameContext context;
  context.ts_ms = 1700000000123;
  context.seq = 7;
  context.event = "tick";
  const json frame = telemetry_frame(kStatus, context);
  for (const char* key : {"ts", "loop_latency_ms", "loop_count", "paused", "estopped", "nav_running", "obstacles", "battery_v"})
    CHECK_MESSAGE(frame.contains(key), key);
  CHECK(frame["type"] == "telemetry");
  CHECK(frame["ts"] == 1700000000123);
  CHECK(frame["seq"] == 7);
  CHECK(frame["event"] == "tick");
  CHECK(frame["loop_latency_ms"].is_null());
  CHECK(frame["loop_count"].is_null());
  CHECK(frame["paused"] == false);
  CHECK(frame["estopped"] == false);
  CHECK(frame["nav_running"] == true);
  CHECK(frame["obstacles"].is_null());
  CHECK(frame["battery_v"] == 12.4);
  CHECK(frame["pose"]["x_m"] == 1.5);
  CHECK(frame["state"] == "running");
  CHECK(frame["uptime_s"] == 42);
  CHECK(frame["capabilities"] == json{{"teleop", "ok"}, {"nav", "stale"}, {"power", "ok"}});
  CHECK(frame["drivers"] == json{{"drive0", "ok"}, {"arm0", "failed"}});
  CHECK(frame["estop"].is_null());
}

TEST_CASE("telemetry frame: latched, pushed, and a document missing everything") {
  json latched = kStatus;
  latched["estopped"] = true;
  latched["state"] = "estop";
  FrameContext context;
  context.event = "estop_latched";
  context.estop = {{"since_ms", 5}, {"reason", "POST /api/stop"}, {"source", "owner"}};
  const json frame = telemetry_frame(latched, context);
  CHECK(frame["estopped"] == true);
  CHECK(frame["event"] == "estop_latched");
  CHECK(frame["estop"]["reason"] == "POST /api/stop");

  const json bare = telemetry_frame(json("not an object"), FrameContext{});
  CHECK(bare["estopped"] == false);
  CHECK(bare["nav_running"] == false);
  CHECK(bare["pose"].is_null());
  CHECK(bare["battery_v"].is_null());
  CHECK(bare["capabilities"] == json::object());
}

TEST_CASE("telemetry frame: obstacles from an ObstacleSource, null when stale or absent") {
  CHECK(obstacles_field(nullptr).is_null());
  CHECK(obstacles_field(std::make_unique<FixedObstacles>(rcand::sdk::ObstacleReading{}).get()).is_null());
  const double inf = std::numeric_limits<double>::infinity();
  FixedObstacles fresh({true, 80.0, 35.5, inf, 35.5, 1700000000000});
  const json field = obstacles_field(&fresh);
  CHECK(field["left_cm"] == 80.0);
  CHECK(field["nearest_cm"] == 35.5);
  CHECK(field["right_cm"].is_null());  // nothing seen there
  CHECK(field["timestamp_ms"] == 1700000000000);
}
