#include "action_object.hpp"

#include <rcand/sdk/contract/requests.hpp>

#include <array>
#include <string>
#include <string_view>
#include <utility>

namespace rcand::plugins::chat {
namespace {

using sdk::Json;
namespace contract = sdk::contract;

// Routes (other than /api/action and custom capabilities) whose request maps to a type of its own. The e-stop is
// "estop", not "stop": in the reference runtime's vocabulary {"type":"stop"} halts the base and latches nothing,
// which is rcand's teleop stop action.
struct RouteType {
  std::string_view method, path, type;
};
constexpr std::array kRouteTypes{
    RouteType{"POST", "/api/stop", "estop"},
    RouteType{"GET", "/api/status", "status"},
    RouteType{"POST", "/api/nav/waypoint", "nav_waypoint"},
    RouteType{"POST", "/api/nav/cancel", "nav_cancel"},
    RouteType{"GET", "/api/nav/status", "nav_status"},
    RouteType{"GET", "/api/depth/obstacles", "obstacles"},
    RouteType{"GET", "/api/stream/snapshot", "snapshot"},
};

// {"type": type} followed by the body's own fields (a body never renames the type).
Json typed(std::string_view type, const Json& body) {
  Json object{{"type", type}};
  if (body.is_object())
    for (const auto& [key, value] : body.items())
      if (key != "type") object[key] = value;
  return object;
}

}  // namespace

Json action_object(const Json& request) {
  if (!request.is_object()) return nullptr;
  const auto method = request.find("method");
  const auto path = request.find("path");
  if (method == request.end() || path == request.end() || !method->is_string() || !path->is_string()) return nullptr;
  const std::string& m = method->get_ref<const std::string&>();
  const std::string& p = path->get_ref<const std::string&>();
  const Json body = request.value("body", Json());

  if (p == contract::kActionPath && body.is_object() && body.contains("type") && body["type"].is_string()) return body;
  for (const auto& route : kRouteTypes)
    if (m == route.method && p == route.path) return typed(route.type, body);
  if (p.rfind(contract::kCustomPrefix, 0) == 0) {
    const std::string rest = p.substr(contract::kCustomPrefix.size());
    const auto slash = rest.find('/');
    return {{"type", "custom"},
            {"capability", rest.substr(0, slash)},
            {"route", slash == std::string::npos ? std::string("/") : rest.substr(slash)},
            {"method", m},
            {"body", body}};
  }
  Json other{{"type", "request"}, {"method", m}, {"path", p}};
  if (!body.is_null()) other["body"] = body;
  return other;
}

}  // namespace rcand::plugins::chat
