#include "obstacle_guard.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace rcand::plugins::obstacle {
namespace {

// docs/protocol.md §8.6: agent.min_obstacle_m (spec), safety.obstacle_stop_cm accepted as an alias; none: no stop.
std::optional<double> read_min_cm(const sdk::ConfigView& robot) {
  std::optional<double> cm;
  std::string key = "agent.min_obstacle_m";
  if (auto m = robot.get<double>(key)) cm = *m * 100.0;
  else if (auto alias = robot.get<double>(key = "safety.obstacle_stop_cm")) cm = *alias;
  if (cm && (!std::isfinite(*cm) || *cm < 0.0))
    throw sdk::ConfigError(key + ": expected a number >= 0, found " + std::to_string(*cm));
  return cm;
}

// camera.depth present and not false: the robot says it has depth, so a missing source is a fault, not "no depth".
bool read_depth_declared(const sdk::ConfigView& robot) {
  const auto& raw = robot.raw();
  if (!raw.is_object() || !raw.contains("camera") || !raw["camera"].is_object()) return false;
  const auto& camera = raw["camera"];
  if (!camera.contains("depth")) return false;
  const auto& depth = camera["depth"];
  return !depth.is_null() && !(depth.is_boolean() && !depth.get<bool>());
}

std::string record_of(const sdk::ObstacleReading& r, bool with_zones, double min_cm) {
  char text[256];
  if (with_zones)
    std::snprintf(text, sizeof text,
                  "[depth available=true left_cm=%.1f center_cm=%.1f right_cm=%.1f nearest_cm=%.1f timestamp_ms=%lld "
                  "min_cm=%.1f]",
                  r.left_cm, r.center_cm, r.right_cm, r.nearest_cm, static_cast<long long>(r.timestamp_ms), min_cm);
  else
    std::snprintf(text, sizeof text, "[depth available=false timestamp_ms=%lld min_cm=%.1f]",
                  static_cast<long long>(r.timestamp_ms), min_cm);
  return text;
}

}  // namespace

Verdict judge(const sdk::ObstacleSource* source, bool depth_declared, std::optional<double> min_cm, std::int64_t now_wall_ms) {
  if (!min_cm) return {};
  if (source == nullptr) {
    if (!depth_declared) return {};
    return {Verdict::Kind::Unavailable, "depth unavailable (camera.depth is declared but no plugin offers the zones)",
            record_of({}, false, *min_cm)};
  }
  const sdk::ObstacleReading r = source->obstacles();
  if (!r.available) {
    // The SDK reading has no reason field; a source that still dates its last frame (vision does) says how old.
    const std::string why = r.timestamp_ms > 0
                                ? "stale: the last depth frame is " +
                                      std::to_string(std::max<std::int64_t>(0, now_wall_ms - r.timestamp_ms)) + " ms old"
                                : "no depth reading";
    return {Verdict::Kind::Unavailable, "depth unavailable (" + why + ")", record_of(r, false, *min_cm)};
  }
  if (!std::isfinite(r.left_cm) || !std::isfinite(r.center_cm) || !std::isfinite(r.right_cm) || !std::isfinite(r.nearest_cm))
    return {Verdict::Kind::Unavailable, "depth unavailable (a non-finite reading)", record_of(r, true, *min_cm)};
  if (r.nearest_cm >= *min_cm) return {};
  char why[128];
  std::snprintf(why, sizeof why, "obstacle at %.1f cm, below the minimum %.1f cm", r.nearest_cm, *min_cm);
  return {Verdict::Kind::Obstacle, why, record_of(r, true, *min_cm)};
}

Guard::Guard(const sdk::PluginContext& ctx)
    : min_cm_(read_min_cm(ctx.robot_config())), depth_declared_(read_depth_declared(ctx.robot_config())) {}

Verdict Guard::check(const sdk::PluginContext& ctx) const {
  if (!min_cm_) return {};  // before the lookup: no minimum, no work
  return judge(sdk::find<sdk::ObstacleSource>(ctx), depth_declared_, min_cm_, ctx.clock().wall_ms());
}

bool Guard::in_play(const sdk::PluginContext& ctx) const {
  return min_cm_ && (depth_declared_ || sdk::find<sdk::ObstacleSource>(ctx) != nullptr);
}

void Guard::latch(sdk::PluginContext& ctx, std::string_view who, const Verdict& verdict, bool moving) noexcept {
  std::string reason;
  try {
    reason = std::string(who) + ": " + verdict.why + (moving ? " while moving " : " ") + verdict.record;
    ctx.log().warn(reason, ": requesting the e-stop");
  } catch (...) {  // no memory for the words: the stop matters, not its wording
  }
  ctx.estop().request_estop(reason);
}

}  // namespace rcand::plugins::obstacle
