// One WS /ws/telemetry frame (docs/protocol.md §7.10), built from GET /api/status's document, never from plugin
// calls. Every MUST field is present; one rcand has no source for is null rather than a made-up number:
//   ts              the wall clock (Unix ms) when the frame was built
//   loop_latency_ms null: rcand runs no perception-action loop (the reference runtime's "loop"); nothing measures one
//   loop_count      null: likewise
//   paused          false: rcand has no pause feature (docs/protocol.md §5 never reports "paused")
//   estopped        the status document's "estopped" (the latch as it is when the frame is built)
//   nav_running     the status document's "nav_running" (the PoseSource's busy flag)
//   obstacles       the ObstacleSource reading (GET /api/depth/obstacles' zones) when one is offered and fresh, else null
//   battery_v       the first numeric "battery_v" a capability publishes in its status, else null (none does today)
// rcand adds: "type":"telemetry", "seq" (frames built since start: a gap shows frames this client missed), "event"
// ("tick", or "estop_latched"/"estop_cleared" for a frame pushed at once), "state", "uptime_s", "pose" (nav's
// dead-reckoned pose or null), "capabilities" and "drivers" ({name: "ok"|"stale"|"error"|"failed"}), and "estop"
// ({"since_ms","reason","source"} while latched, else null).
#pragma once

#include <cstdint>
#include <string_view>

#include <nlohmann/json.hpp>

#include "rcand/sdk/interfaces/obstacle_source.hpp"

namespace rcand::services::telemetry {

struct FrameContext {
  std::int64_t ts_ms = 0;
  std::uint64_t seq = 0;
  std::string_view event = "tick";
  nlohmann::json estop = nullptr;      // {"since_ms","reason","source"} while latched
  nlohmann::json obstacles = nullptr;  // obstacles_field()
};

nlohmann::json telemetry_frame(const nlohmann::json& status, const FrameContext& context);

// The "obstacles" field from a reading: null without a source or without fresh data.
nlohmann::json obstacles_field(const sdk::ObstacleSource* source);

// "ok", "stale", "degraded", "error" or "failed" for one capability or driver item of the status document (error: it
// reports a fault, or every actuator a capability needs failed; degraded: some did; docs/protocol.md §7.2).
std::string_view item_state(const nlohmann::json& item);

}  // namespace rcand::services::telemetry
