// The embedded grammar brain (provider "grammar"): English commands for the standard capabilities and for the
// phrases the robot config declares, read deterministically in microseconds with no network. It reads the whole
// instruction or nothing: a word it cannot place makes the answer "not understood" with the closest commands it
// knows as suggestions, never a guess. Confidence is 1.0 for an exact reading and lower when it had to correct a
// misspelt word ("foward").
//
// What it proposes (chat validates and dispatches it):
//   stop, halt, emergency stop, stop all motors   POST /api/stop (the latched e-stop: the safe reading of "stop")
//   status, how are you                           GET /api/status
//   where are you, navigation status              GET /api/nav/status
//   go forward 1 metre, turn left 90 degrees,     POST /api/nav/waypoint {distance_m, heading_deg, speed}; without
//   turn left and drive 2 m, back up 20 cm slowly   nav, teleop moves timed from the physics block
//   go to x 1 y 2, navigate to 1.5, 2, go home    POST /api/nav/waypoint from the pose nav reports
//   go forward for 3 seconds, spin right          POST /api/action {"type":"move", linear, angular, duration_ms}
//   cancel navigation                             POST /api/nav/cancel
//   what do you see, any obstacles                GET /api/depth/obstacles; take a picture: GET /api/stream/snapshot
//   open / close the gripper (standard arm)       POST /api/action {"type":"grip","state"}
//   configured phrases (custom capabilities)      their configured action
// Speeds: 0.5 by default, "slowly" 0.25, "very slowly" 0.1, "quickly" 0.8, "full speed" 1, "at 30 percent" 0.3.
// A move with neither distance nor duration lasts 1 s; "turn left" alone is 90 degrees, "turn around" 180.
#pragma once

#include <rcand/sdk/interfaces/brain.hpp>

#include <string_view>

namespace rcand::plugins::chat {

class GrammarBrain final : public sdk::Brain {
 public:
  static constexpr std::string_view kProvider = "grammar";
  static constexpr std::string_view kModel = "grammar-en-1";
  static constexpr double kDefaultSpeed = 0.5;
  static constexpr int kDefaultMoveMs = 1000;

  std::string_view provider() const noexcept override { return kProvider; }
  sdk::Proposal propose(const sdk::BrainRequest& request, const sdk::BrainContext& context,
                        sdk::CancelToken cancel) const noexcept override;

  // The reading itself, for tests: pure and deterministic.
  static sdk::Proposal understand(std::string_view instruction, const sdk::BrainContext& context);
};

}  // namespace rcand::plugins::chat
