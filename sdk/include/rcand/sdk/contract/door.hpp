// The one door every capability request goes through, on the robot (kernel/api/) and on the SDK's fake host: the
// capability route table both build from the routes the running capabilities registered (route_table), the row a
// request matches (match), and whether it may run (decide), in the kernel's order (docs/protocol.md §7): the row's
// scope (403) first, then the e-stop (423) for motion rows; a fallback row (Unserved) then answers for a capability
// that is not declared (404), still starting or out of service (503 STARTING / UNAVAILABLE, the kernel only: the fake
// host starts a capability before it serves) or has no such route (405/404). Pure and
// header-only; tests/unit/contract runs every row of the table through both hosts.
#pragma once

#include <algorithm>
#include <cstddef>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "rcand/sdk/contract/requests.hpp"
#include "rcand/sdk/contract/route_match.hpp"

namespace rcand::sdk::contract {

enum class RowKind {
  Route,     // a route the capability registered: its handler runs
  Stream,    // a stream route the capability registered
  Action,    // POST /api/action itself: the body's "type" picks the type's own row
  Unserved,  // a mount's, an action type's or /api/cap/*'s fallback: the capability is not declared, not running,
             // or has no such route
};

// One row of the capability route table.
struct RouteRow {
  std::string method;            // "GET", "POST", or "*" for any method
  std::string path;              // exact, or a prefix ending in '*' (exact rows win, then the longest prefix)
  std::string action_type;       // a POST /api/action type's row: the body's "type"; empty for every other row
  std::string capability;        // who serves it (for a fallback: the mount's owner; "" under /api/cap/*: named by the path)
  Scope scope = Scope::Control;  // what the caller needs (route_scope applied)
  bool motion = false;           // 423 while the e-stop is latched
  RowKind kind = RowKind::Route;
  std::string route_path;  // Route/StreamRoute::path as the capability registered it (the kernel's lookup key)
};

// A route as a capability registered it (sdk::Route, or sdk::StreamRoute with `stream`).
struct DeclaredRoute {
  std::string method, path, action_type;
  Scope scope = Scope::Control;
  bool motion = false, stream = false;
};
struct RunningCapability {
  std::string name;
  std::vector<DeclaredRoute> routes;
};

inline RowMatch<RouteRow> match(const std::vector<RouteRow>& rows, std::string_view method, std::string_view path,
                                std::string_view action_type = {}) {
  return match_rows(
      rows,
      [](const RouteRow& r) {
        return RowKey{r.method, r.path, r.action_type};
      },
      method, path, action_type);
}

// Whether a standard capability's route at `path` lies inside its mounts (custom capabilities' always do).
inline bool within_mounts(const StandardCapability* standard, std::string_view path) noexcept {
  return !standard || std::any_of(standard->mounts.begin(), standard->mounts.end(), [&](std::string_view mount) {
    return mount.ends_with('*') ? path.starts_with(mount.substr(0, mount.size() - 1)) : path == mount;
  });
}

// The table both hosts serve: each running capability's routes (standard ones at their mounts, custom ones under
// /api/cap/<name>, /api/action types on their own rows), then the fallbacks: per standard mount (GET needs status,
// any other method control) unless a route already serves it, per standard action type not served, and /api/cap/*.
// A route outside its capability's mounts, of another capability's action type, or registered twice is not served:
// it is named in `refused`.
struct RouteTable {
  std::vector<RouteRow> rows;
  std::vector<std::string> refused;  // "capability <name>: route <method> <path> ..." for each route left out
};
inline RouteTable route_table(const std::vector<RunningCapability>& running) {
  RouteTable table;
  auto& rows = table.rows;
  for (const auto& cap : running) {
    const StandardCapability* standard = find_standard(cap.name);
    for (const auto& r : cap.routes) {
      const bool action = !r.action_type.empty() && !r.stream;
      const std::string path = action ? std::string(kActionPath) : served_path(cap.name, r.path);
      auto refuse = [&](const char* why) {
        table.refused.push_back("capability " + cap.name + ": route " + r.method + " " + path + " " + why);
      };
      if (action && (standard == nullptr || r.method != "POST" || r.path != kActionPath ||
                     std::find(standard->action_types.begin(), standard->action_types.end(), r.action_type) ==
                         standard->action_types.end())) {
        refuse(("serves an action type ('" + r.action_type + "') that is not its own; not served").c_str());
        continue;
      }
      if (!action && !within_mounts(standard, path)) {
        refuse("is outside its endpoints; not served");
        continue;
      }
      if (std::any_of(rows.begin(), rows.end(), [&](const RouteRow& row) {
            return row.method == r.method && row.path == path && row.action_type == (action ? r.action_type : "");
          })) {
        refuse("registered twice; the first one is served");
        continue;
      }
      rows.push_back({r.method, path, action ? r.action_type : "", cap.name, route_scope(r.scope, r.method, !standard),
                      r.motion && !r.stream, r.stream ? RowKind::Stream : RowKind::Route, r.path});
    }
  }
  const std::size_t served = rows.size();
  auto is_served = [&](std::string_view method, std::string_view path, std::string_view type) {
    const RouteRow* row = match_rows(
                              std::span(rows.data(), served),
                              [](const RouteRow& r) {
                                return RowKey{r.method, r.path, r.action_type};
                              },
                              method, path, type)
                              .row;
    // a prefix mount is served only by that very row
    return row != nullptr && (!path.ends_with('*') || (row->path == path && row->method == method));
  };
  for (const auto& cap : standard_capabilities()) {
    for (auto mount : cap.mounts)
      for (const char* method : {"GET", "*"})
        if (!is_served(method, mount, {}))
          rows.push_back({method, std::string(mount), "", std::string(cap.name),
                          method == std::string_view("GET") ? Scope::Status : Scope::Control, false, RowKind::Unserved, ""});
    for (auto type : cap.action_types)
      if (!is_served("POST", kActionPath, type))
        rows.push_back({"POST", std::string(kActionPath), std::string(type), std::string(cap.name), Scope::Control, false,
                        RowKind::Unserved, ""});
  }
  const std::string custom = std::string(kCustomPrefix) + "*";
  rows.push_back({"GET", custom, "", "", Scope::Control, false, RowKind::Unserved, ""});
  rows.push_back({"*", custom, "", "", Scope::Control, false, RowKind::Unserved, ""});
  rows.push_back({"POST", std::string(kActionPath), "", "", Scope::Control, false, RowKind::Action, ""});
  return table;
}

// A row for a route as the capability has it now (a reloaded plugin's routes replace the ones the table was built
// from): what decide() needs of it.
inline RouteRow live_row(const std::string& capability, const std::string& method, Scope declared, bool motion) {
  return {method,         "", "", capability, route_scope(declared, method, find_standard(capability) == nullptr), motion,
          RowKind::Route, ""};
}

// ---- the decision -------------------------------------------------------------------------------------------

struct Caller {
  std::string who;  // as refusals name it ("principal 'alice'", "role user")
  std::span<const Scope> scopes;
};
struct Verdict {
  bool run = true;   // false: answer `refusal`
  Response refusal;  // 403 or 423
  std::string why;   // the refusal in the audit log's words
};

// Whether a request a row matched may go on: the row's scope, then the e-stop for a motion row.
template <class Row> Verdict decide(const Caller& caller, const Row& row, bool latched) {
  if (row.scope != Scope::None && std::find(caller.scopes.begin(), caller.scopes.end(), row.scope) == caller.scopes.end())
    return {false, insufficient_scope(caller.who, row.scope), "insufficient privileges"};
  if (row.motion && latched) return {false, estop_active(), "e-stop active"};
  return {};
}

// POST /api/action's body: its "type", or the 400 that names the field; `declared` lists the types of the
// capabilities declared.
inline std::string action_type_of(const Json& body, const std::vector<std::string>& declared, Response& refusal) {
  if (!body.is_object() || !body.contains("type") || !body["type"].is_string()) {
    refusal = missing_action_type(declared);
    return {};
  }
  std::string type = body["type"].get<std::string>();
  if (capability_of_action(type) == nullptr) refusal = unknown_action_type(type, declared);
  return type;
}

// The capability a request answered by an Unserved row of `owner` is for (under /api/cap/: the one the path names),
// and its route path below the prefix (`subpath`) for a custom one.
inline std::string unserved_capability(const std::string& owner, std::string_view path, std::string* subpath = nullptr) {
  if (!path.starts_with(kCustomPrefix)) return owner;
  const std::string_view rest = path.substr(kCustomPrefix.size());
  const std::string_view name = rest.substr(0, rest.find('/'));
  if (subpath != nullptr) *subpath = std::string(rest.substr(name.size()));
  return std::string(name);
}

// What an Unserved row answers for a running capability `name` whose routes (`methods`: those at this path) did not
// match: 405 when the path has other methods, else 404.
inline Response no_route(const std::string& name, std::string_view method, std::string_view path,
                         std::vector<std::string> methods) {
  if (!methods.empty()) return method_not_allowed(std::string(method), std::string(path), std::move(methods));
  return no_endpoint(name, std::string(path));
}

}  // namespace rcand::sdk::contract
