// The depth obstacle rule (RCAN §12, docs/protocol.md §8.6 and §13.5.3, issue 15), one rule for every plugin that
// drives wheels: nav and teleop both compile this file, so "blocked" means the same thing for a waypoint and for a
// joystick (the SDK, which would be the natural home, only carries the reading).
//
// With a minimum configured (agent.min_obstacle_m, alias safety.obstacle_stop_cm) and depth in play (an
// ObstacleSource is offered, or camera.depth is declared), a reading is:
//  - Clear: available, finite, nearest_cm >= the minimum;
//  - Obstacle: nearest_cm below the minimum;
//  - Unavailable: no source although camera.depth is declared, no fresh reading (stale, camera down, warming up),
//    or a non-finite zone. Depth that cannot be read is not free space: while the robot moves it is a stop.
// Without a minimum, or with no source and no depth declared, every reading is Clear (nothing to check against).
//
// The reading goes into the e-stop reason, which the kernel audits and shows in GET /api/estop (its audit API takes
// text only), in one fixed form after the words, parsable as space-separated key=value pairs:
//   nav: obstacle at 20.0 cm, below the minimum 30.0 cm [depth available=true left_cm=45.0 center_cm=20.0
//     right_cm=400.0 nearest_cm=20.0 timestamp_ms=1712345678901 min_cm=30.0]
//   nav: depth unavailable (stale: the last depth frame is 340 ms old) while moving [depth available=false
//     timestamp_ms=1712345678561 min_cm=30.0]
// (one line each; timestamp_ms is the depth frame's Unix time, 0 when there never was one).
#pragma once

#include <rcand/sdk/plugin.hpp>

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

namespace rcand::plugins::obstacle {

// How often a moving robot re-reads the zones: 40 Hz (§10.5 asks >= 10 Hz). Issue 15's budget from the depth frame
// to halted motors is p99 < 50 ms, and a 50 ms period alone spends all of it (bench/run-depth-halt.sh: p99 50.8 ms at
// 20 Hz, 25.8 ms at 40 Hz); a check is a lock and a copy, so the faster rate costs nothing that matters.
inline constexpr std::chrono::milliseconds kCheckPeriod{25};

struct Verdict {
  enum class Kind { Clear, Obstacle, Unavailable };
  Kind kind = Kind::Clear;
  std::string why;     // "obstacle at 20.0 cm, below the minimum 30.0 cm" / "depth unavailable (stale: ...)"
  std::string record;  // "[depth available=... min_cm=...]": the reading, in the fixed form above
  bool clear() const noexcept { return kind == Kind::Clear; }
};

// `source` null: none offered. `now_wall_ms` dates a stale reading's frame.
Verdict judge(const sdk::ObstacleSource* source, bool depth_declared, std::optional<double> min_cm, std::int64_t now_wall_ms);

class Guard {
 public:
  // Reads the minimum (throws sdk::ConfigError naming the key when it is negative or not finite) and whether
  // camera.depth is declared.
  explicit Guard(const sdk::PluginContext& ctx);

  std::optional<double> min_cm() const noexcept { return min_cm_; }
  // Whether a reading can ever be anything but Clear now: a minimum, and depth declared or a source offered. A
  // moving robot without depth has nothing to re-read (a fleet of them would spend a core on 40 Hz no-op checks).
  bool in_play(const sdk::PluginContext& ctx) const;
  // Reads the robot's ObstacleSource now. Any thread; never blocks beyond the source's copy.
  Verdict check(const sdk::PluginContext& ctx) const;
  // Latches the e-stop (as POST /api/stop; the kernel audits it naming the plugin) with
  // "<who>: <why>[ while moving] <record>". Returns after the drivers halted.
  static void latch(sdk::PluginContext& ctx, std::string_view who, const Verdict& verdict, bool moving) noexcept;

 private:
  std::optional<double> min_cm_;
  bool depth_declared_ = false;
};

}  // namespace rcand::plugins::obstacle
