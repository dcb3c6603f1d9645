// A capability (§9): a named feature with HTTP routes. Standard names are status, nav, teleop, vision,
// chat and arm; custom ones are reverse-domain (com.acme.gripper) and serve under /api/cap/<name>/.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "rcand/sdk/export.hpp"
#include "rcand/sdk/http.hpp"
#include "rcand/sdk/scope.hpp"
#include "rcand/sdk/stream.hpp"

namespace rcand::sdk {

struct Route {
  std::string method;  // "GET", "POST", ...
  // Standard capabilities: the absolute path ("/api/nav/waypoint"). Custom capabilities: the path below
  // "/api/cap/<name>" ("/grip" serves "/api/cap/com.acme.gripper/grip"; "" serves the prefix itself).
  std::string path;
  Scope scope = Scope::Control;  // the kernel raises custom capabilities' routes to at least Control (§9.4)
  bool motion = false;           // true: refused with 423 while the e-stop is latched, before the handler runs
  // For POST /api/action only: the body "type" this route serves ("move", "stop", "grip", ...).
  std::string action_type;
  // Runs on the capability's own worker thread ("cap.<name>"), one request at a time. May block, up to
  // runtime.handler_timeout_ms, after which the caller gets 503 and the capability is marked failed.
  // Check the body before reading it (rcand/sdk/request_body.hpp: a 400 naming the field). An exception is caught by
  // the kernel: that request gets 500 INTERNAL and is counted (handler_errors); the capability stays in service
  // (docs/protocol.md §7.16).
  std::function<Response(const Request&)> handler;
};

class RCAND_INTERFACE Capability {
 public:
  virtual ~Capability() = default;
  // Main thread, once, after construction. May block briefly. Throw to fail the instance.
  virtual void start() {}
  // Main thread, once, after start(). The routes this capability serves.
  virtual std::vector<Route> routes() = 0;
  // The instance's status thread, for GET /api/status (under "capabilities.<name>"). Thread-safe; must not block:
  // one that has not returned after 250 ms fails the instance and is never called again. A status (returned or
  // published) with a top-level "fault" - a non-empty string, the fault in words an operator can act on ("camera
  // device /dev/video3 does not exist") - says the instance runs but cannot do its job: GET /api/status and telemetry
  // show its state as "error" with the fault as "reason" (cut to 600 bytes), and the robot's state as "error", until
  // a status without one (null or absent). Drivers' statuses follow the same rule.
  virtual Json status() const { return Json::object(); }
  // The stop path, right after every actuating driver halted. Cancel running jobs; must not block.
  virtual void on_estop() noexcept {}
  // A kernel thread, once, at shutdown (in parallel with other capabilities'). Stop jobs and return; the kernel joins
  // the workers afterwards. One still running after 2 s is left behind.
  virtual void shutdown() noexcept {}
  // ABI 1.2, appended last: routes that answer with a stream or binary body (rcand/sdk/stream.hpp). Main thread, once,
  // after routes(). The kernel calls it only for plugins whose descriptor declares minor 2 or later (older ones have
  // no such slot in their vtable); their JSON routes are unchanged.
  virtual std::vector<StreamRoute> stream_routes() { return {}; }
};

}  // namespace rcand::sdk
