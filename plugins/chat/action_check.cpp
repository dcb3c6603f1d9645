#include "action_check.hpp"

#include <rcand/sdk/contract/requests.hpp>
#include <rcand/sdk/request_body.hpp>

#include <algorithm>
#include <cmath>

namespace rcand::plugins::chat {
namespace {

using sdk::Json;
using sdk::Response;
namespace contract = sdk::contract;

Response rejected(const std::string& where, const std::string& why) {
  return Response::error(422, "ACTION_REJECTED", "the brain's action was refused: " + why,
                         Json{{"field", "action"}, {"at", where}});
}

bool declared(const ActionLimits& limits, const std::string& name) {
  return std::find(limits.declared.begin(), limits.declared.end(), name) != limits.declared.end();
}

// A finite number in [-limit, limit] at body[key]; required unless `optional`.
std::optional<Response> number_in(const Json& body, const char* key, double limit, bool optional, double& out) {
  const auto it = body.find(key);
  if (it == body.end()) {
    if (optional) return std::nullopt;
    return rejected(std::string("body.") + key, std::string(key) + " is required");
  }
  if (!it->is_number() || !std::isfinite(it->get<double>()))
    return rejected(std::string("body.") + key, std::string(key) + " must be a finite number");
  out = it->get<double>();
  if (std::abs(out) > limit)
    return rejected(std::string("body.") + key, std::string(key) + " " + it->dump() + " is outside [-" + Json(limit).dump() +
                                                    ", " + Json(limit).dump() + "]");
  return std::nullopt;
}

std::optional<Response> check_move(const Json& body, const ActionLimits& limits) {
  double linear = 0, angular = 0, unused = 0;
  if (auto bad = number_in(body, "linear", limits.max_linear_speed, true, linear)) return bad;
  if (auto bad = number_in(body, "angular", 1.0, true, angular)) return bad;
  // A brain's move always ends by itself: duration_ms is required and bounded.
  const auto it = body.find("duration_ms");
  if (it == body.end() || !it->is_number_integer() || it->get<double>() < 1 || it->get<double>() > limits.max_duration_ms)
    return rejected("body.duration_ms", "a move needs duration_ms, an integer in [1, " + std::to_string(limits.max_duration_ms) +
                                            "] (runtime.capabilities.chat.max_duration_ms)");
  (void)unused;
  return std::nullopt;
}

std::optional<Response> check_waypoint(const Json& body, const ActionLimits& limits) {
  double distance = 0, heading = 0, speed = 0.5;
  if (auto bad = number_in(body, "distance_m", limits.max_distance_m, false, distance)) return bad;
  if (auto bad = number_in(body, "heading_deg", limits.max_turn_deg, false, heading)) return bad;
  if (auto bad = number_in(body, "speed", limits.max_linear_speed, true, speed)) return bad;
  if (!(speed > 0)) return rejected("body.speed", "speed must be in (0, " + Json(limits.max_linear_speed).dump() + "]");
  // The job's duration as nav times it (seed §10): refused here when nav would refuse it, or run past its limit.
  if (limits.wheel_circumference_m > 0 && limits.turn_time_per_deg_s > 0 && limits.max_wheel_rps > 0) {
    const double seconds = std::abs(heading) * limits.turn_time_per_deg_s / speed +
                           std::abs(distance) / (limits.wheel_circumference_m * limits.max_wheel_rps * speed);
    if (seconds * 1000.0 > static_cast<double>(limits.nav_max_job_ms))
      return rejected("body", "the waypoint would take " + std::to_string(seconds) + " s, over nav's max_job_ms");
  }
  return std::nullopt;
}

}  // namespace

std::variant<CheckedAction, sdk::Response> check_action(const Json& action, const ActionLimits& limits) {
  if (!action.is_object()) return rejected("action", "an action is an object with method, path and body");
  const auto method = action.find("method");
  const auto path = action.find("path");
  if (method == action.end() || !method->is_string() || (*method != "GET" && *method != "POST"))
    return rejected("method", "method must be GET or POST");
  if (path == action.end() || !path->is_string() || path->get<std::string>().rfind("/api/", 0) != 0 ||
      path->get<std::string>().size() > 256 || path->get<std::string>().find_first_of("?#%\\ ") != std::string::npos ||
      path->get<std::string>().find("..") != std::string::npos)
    return rejected("path", "path must be a plain /api/... path");
  CheckedAction c;
  c.method = method->get<std::string>();
  c.path = path->get<std::string>();
  const bool get = c.method == "GET";
  if (const auto body = action.find("body"); body != action.end() && !body->is_null()) {
    if (get) return rejected("body", "a GET has no body");
    if (!body->is_object()) return rejected("body", "body must be an object");
    c.body = *body;
  } else if (!get) {
    c.body = Json::object();
  }
  c.scope = get ? sdk::Scope::Status : sdk::Scope::Control;
  c.motion = !get;

  // rcand's own routes a brain may use: the stop (always), and the status read. Nothing else of rcand's.
  if (c.method == "POST" && c.path == "/api/stop") {
    c.scope = sdk::Scope::Status;
    c.motion = false;
    c.stop = true;
    return c;
  }
  if (c.method == "GET" && c.path == "/api/status") return c;

  // Custom capabilities under /api/cap/<name>/...: declared ones only; their handlers check their bodies.
  if (c.path.rfind(contract::kCustomPrefix, 0) == 0) {
    const std::string rest = c.path.substr(contract::kCustomPrefix.size());
    c.capability = rest.substr(0, rest.find('/'));
    if (c.capability.empty() || contract::find_standard(c.capability) != nullptr)
      return rejected("path", "no custom capability in " + c.path);
    c.scope = sdk::Scope::Control;  // custom capabilities need control (§9.4)
  } else if (c.path == contract::kActionPath) {
    if (get) return rejected("method", "POST /api/action only");
    const auto type = c.body.find("type");
    if (type == c.body.end() || !type->is_string()) return rejected("body.type", "an action needs a type");
    const auto* standard = contract::capability_of_action(type->get<std::string>());
    if (standard == nullptr) return rejected("body.type", "unknown action type " + sdk::describe_value(*type));
    c.capability = std::string(standard->name);
    if (*type == "stop") c.motion = false;
    if (*type == "move")
      if (auto bad = check_move(c.body, limits)) return *bad;
    if (*type == "grip" && (!c.body.contains("state") || (c.body["state"] != "open" && c.body["state"] != "close")))
      return rejected("body.state", "a grip needs state open or close");
  } else {
    for (const auto& cap : contract::standard_capabilities())
      for (auto mount : cap.mounts)
        if (mount.ends_with('*') ? c.path.rfind(mount.substr(0, mount.size() - 1), 0) == 0 : c.path == mount)
          c.capability = std::string(cap.name);
    if (c.capability.empty()) return rejected("path", c.path + " is not a route a brain may use");
    if (c.capability == "chat") return rejected("path", "chat never dispatches to its own route");
    if (c.method == "POST" && c.path == "/api/nav/waypoint") {
      if (auto bad = check_waypoint(c.body, limits)) return *bad;
    } else if (c.method == "POST" && c.path == "/api/nav/cancel") {
      c.motion = false;  // a stop of the running job
    } else if (!(get && (c.path == "/api/nav/status" || c.path == "/api/depth/obstacles" || c.path == "/api/stream/snapshot"))) {
      // Streams never end and other routes are not for brains.
      return rejected("path", c.method + " " + c.path + " is not a route a brain may use");
    }
  }
  if (!declared(limits, c.capability))
    return Response::error(404, "CAPABILITY_NOT_FOUND",
                           "the brain's action needs the '" + c.capability + "' capability, which this robot does not declare",
                           Json{{"field", "action"}, {"capability", c.capability}, {"capabilities", limits.declared}});
  if (c.capability == "chat") return rejected("path", "chat never dispatches to its own route");
  return c;
}

}  // namespace rcand::plugins::chat
