// The request rules the kernel and the SDK's fake host share (RCAN §9, docs/protocol.md §4 and §7), so a vendor test
// that passes on the fake host passes on the robot: which capability serves which endpoint and /api/action type,
// the scope a route needs, and the exact answer for each refusal. Pure and header-only; both hosts call these and
// tests/unit/contract runs one table of requests through both.
#pragma once

#include <algorithm>
#include <array>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "rcand/sdk/bounded_text.hpp"
#include "rcand/sdk/http.hpp"
#include "rcand/sdk/scope.hpp"

namespace rcand::sdk::contract {

using namespace std::string_view_literals;

inline constexpr std::string_view kCustomPrefix = "/api/cap/";
inline constexpr std::string_view kActionPath = "/api/action";

// A standard capability (RCAN §9.2): its scope, where its routes are mounted (exact paths, or prefixes ending in
// '*'), and the /api/action types it serves.
struct StandardCapability {
  std::string_view name;
  Scope scope;
  std::string_view endpoint;  // its standard endpoint, as advertised
  std::span<const std::string_view> mounts;
  std::span<const std::string_view> action_types;
};

namespace detail {
inline constexpr std::array kNavMounts{"/api/nav/*"sv};
inline constexpr std::array kVisionMounts{"/api/stream/*"sv, "/api/depth/*"sv};
inline constexpr std::array kChatMounts{"/api/command"sv, "/api/thoughts/*"sv, "/api/hitl/*"sv};
inline constexpr std::array kArmMounts{"/api/arm/*"sv};
inline constexpr std::array kTeleopActions{"move"sv, "stop"sv};
inline constexpr std::array kArmActions{"grip"sv, "arm_pose"sv};
inline constexpr std::array<StandardCapability, 6> kStandard{{
    {"status", Scope::Status, "GET /api/status", {}, {}},
    {"nav", Scope::Control, "POST /api/nav/waypoint", kNavMounts, {}},
    {"teleop", Scope::Control, "POST /api/action", {}, kTeleopActions},
    {"vision", Scope::Status, "GET /api/stream/mjpeg", kVisionMounts, {}},
    {"chat", Scope::Control, "POST /api/command", kChatMounts, {}},
    {"arm", Scope::Control, "POST /api/action", kArmMounts, kArmActions},
}};
}  // namespace detail

inline constexpr std::span<const StandardCapability> standard_capabilities() noexcept { return detail::kStandard; }

inline const StandardCapability* find_standard(std::string_view name) noexcept {
  for (const auto& cap : detail::kStandard)
    if (cap.name == name) return &cap;
  return nullptr;
}

inline const StandardCapability* capability_of_action(std::string_view type) noexcept {
  for (const auto& cap : detail::kStandard)
    if (std::find(cap.action_types.begin(), cap.action_types.end(), type) != cap.action_types.end()) return &cap;
  return nullptr;
}

// The path a capability's route is served at: standard routes are absolute, custom ones sit under
// /api/cap/<name> ("" serves the prefix itself).
inline std::string served_path(std::string_view capability, const std::string& route_path) {
  if (find_standard(capability) != nullptr) return route_path;
  return std::string(kCustomPrefix) + std::string(capability) + route_path;
}

inline Scope stricter(Scope a, Scope b) noexcept { return minimum_role(a) >= minimum_role(b) ? a : b; }

// The scope a request to a capability's route needs: the route's own, raised to status for reading a standard
// capability and to control for anything else, and for every custom capability (RCAN §9.4).
inline Scope route_scope(Scope declared, std::string_view method, bool custom) noexcept {
  const bool reads = method == "GET" || method == "HEAD";
  return stricter(declared, custom || !reads ? Scope::Control : Scope::Status);
}

// ---- the answers both hosts give ---------------------------------------------------------------------------
// What the caller sent (a type, a capability name, a path, a method) is quoted through bounded_text here, so both
// hosts quote it the same way, cut and made safe.

inline Response missing_action_type(std::vector<std::string> allowed) {
  return Response::error(400, "BAD_REQUEST", "body needs a string \"type\"",
                         Json{{"field", "type"}, {"allowed", std::move(allowed)}});
}
inline Response unknown_action_type(const std::string& type, std::vector<std::string> allowed) {
  return Response::error(400, "BAD_REQUEST", "unknown action type '" + bounded_text(type) + "'",
                         Json{{"field", "type"}, {"allowed", std::move(allowed)}});
}
inline Response not_declared(const std::string& capability, std::vector<std::string> declared) {
  const std::string quoted = bounded_text(capability);
  return Response::error(404, "CAPABILITY_NOT_FOUND", "this robot does not declare the '" + quoted + "' capability",
                         Json{{"capability", quoted}, {"capabilities", std::move(declared)}});
}
inline Response no_endpoint(const std::string& capability, const std::string& path) {
  return Response::error(404, "NOT_FOUND", "capability '" + bounded_text(capability) + "' has no endpoint " + bounded_text(path));
}
inline Response method_not_allowed(const std::string& method, const std::string& path, std::vector<std::string> allowed) {
  return Response::error(405, "METHOD_NOT_ALLOWED", bounded_text(method) + " is not allowed on " + bounded_text(path),
                         Json{{"allowed", std::move(allowed)}});
}
inline Response insufficient_scope(const std::string& who, Scope scope) {
  return Response::error(403, "INSUFFICIENT_PRIVILEGES", who + " lacks scope '" + std::string(scope_name(scope)) + "'",
                         Json{{"required_scope", scope_name(scope)}});
}
inline Response estop_active() {
  return Response::error(423, "ESTOP_ACTIVE", "e-stop is latched; clear it with POST /api/estop/clear");
}
inline Response out_of_service(const std::string& capability, const std::string& why) {
  return Response::error(503, "UNAVAILABLE", "capability '" + capability + "' is out of service: " + why,
                         Json{{"capability", capability}});
}
// The capability is declared and its plugin's start() has not returned yet (rcand serves while capabilities start):
// ask again shortly. Only the robot answers it (the fake host starts a capability before it serves).
inline Response starting(const std::string& capability) {
  return Response::error(503, "STARTING", "capability '" + capability + "' is starting; ask again shortly",
                         Json{{"capability", capability}, {"state", "starting"}});
}
// A request handler threw (docs/protocol.md §7.16): this request fails; the capability stays in service.
inline Response handler_threw(const std::string& capability) {
  return Response::error(500, "INTERNAL", "capability '" + capability + "' failed while handling this request (logged)");
}

// A handler's answer as it reaches the client: the error shape (docs/protocol.md §4) guaranteed on every non-2xx
// status, and an invalid status replaced by a 500.
inline Response normalized(const Response& answer) {
  if (answer.status < 100 || answer.status > 599)
    return Response::error(500, "INTERNAL", "capability answered an invalid status");
  if (answer.status < 300) return answer;
  Json body = answer.body.is_object() ? answer.body : Json::object();
  if (!body.contains("error")) body["error"] = "request failed";
  if (!body.contains("code")) body["code"] = answer.status >= 500 ? "INTERNAL" : "BAD_REQUEST";
  body["status"] = answer.status;
  return {answer.status, std::move(body)};
}

}  // namespace rcand::sdk::contract
