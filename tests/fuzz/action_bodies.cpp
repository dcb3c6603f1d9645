// libFuzzer target: the action bodies of the motion capabilities - teleop (move, stop), arm (arm_pose, grip, joint
// state) and nav (waypoint, cancel, status) - through the real Api of the simulated robot, as the owner. The first
// byte picks the route; for POST /api/action it also names the action type, written into the body when the body is
// a JSON object (so every input reaches that capability's handler rather than the type dispatch), or the body goes
// as it is. Invariants: those of every answer (sim_robot.hpp: a status, never 500, errors {"error","code","status"}),
// and for what was accepted: an arm command's targets lie inside their joints' limits at no more than their speed
// limit (physics.kinematics of the sim robot), a move's speeds inside [-1, 1].
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <map>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "fuzz_check.hpp"
#include "sim_robot.hpp"

namespace {

using nlohmann::json;

struct Route {
  const char* method;
  const char* path;
  const char* action_type;  // written into an object body; nullptr: the body as it is
};

constexpr Route kRoutes[] = {
    {"POST", "/api/action", "move"},      {"POST", "/api/action", "stop"},     {"POST", "/api/action", "arm_pose"},
    {"POST", "/api/action", "grip"},      {"POST", "/api/action", nullptr},    {"POST", "/api/nav/waypoint", nullptr},
    {"POST", "/api/nav/cancel", nullptr}, {"GET", "/api/nav/status", nullptr}, {"GET", "/api/arm/joints", nullptr},
};

struct Limit {
  double min_deg, max_deg, max_velocity_dps;
};
// The sim robot's physics.kinematics (sim_robot.cpp).
const std::map<std::string, Limit> kJoints{{"shoulder", {-90, 90, 60}}, {"elbow", {0, 135, 90}}, {"gripper", {0, 60, 120}}};

void check_arm_answer(const json& answer) {
  RCAND_FUZZ_CHECK(answer.contains("targets") && answer["targets"].is_object(), "an arm answer lists its targets");
  for (const auto& [joint, deg] : answer.at("targets").items()) {
    const auto limit = kJoints.find(joint);
    RCAND_FUZZ_CHECK(limit != kJoints.end(), "an arm target names a configured joint");
    RCAND_FUZZ_CHECK(deg.is_number() && deg.get<double>() >= limit->second.min_deg && deg.get<double>() <= limit->second.max_deg,
                     "an arm target lies inside its joint's limits");
    const json speed = answer.value("velocity_dps", json::object()).value(joint, json());
    RCAND_FUZZ_CHECK(speed.is_number() && speed.get<double>() > 0 && speed.get<double>() <= limit->second.max_velocity_dps,
                     "an arm target moves no faster than its joint's limit");
  }
}

void check_move_body(const json& body) {
  for (const char* key : {"linear", "angular"})
    if (body.contains(key) && body[key].is_number())
      RCAND_FUZZ_CHECK(std::abs(body[key].get<double>()) <= 1.0, "an accepted move's speeds lie in [-1, 1]");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const Route& route = kRoutes[data[0] % std::size(kRoutes)];
  std::string body(reinterpret_cast<const char*>(data) + 1, size - 1);
  json parsed = json::parse(body, nullptr, false);
  if (route.action_type && parsed.is_object()) {
    parsed["type"] = route.action_type;
    body = parsed.dump(-1, ' ', false, json::error_handler_t::replace);
  }
  const auto response = rcand::fuzz::call(rcand::fuzz::owner_request(route.method, route.path, body));
  if (response.status == 200 && route.action_type) {
    const json answer = json::parse(response.body, nullptr, false);
    RCAND_FUZZ_CHECK(answer.is_object(), "an accepted action answers a JSON object");
    const std::string type = route.action_type;
    if (type == "arm_pose" || type == "grip") check_arm_answer(answer);
    if (type == "move") check_move_body(parsed);
  }
  rcand::fuzz::reset_robot();
  return 0;
}
