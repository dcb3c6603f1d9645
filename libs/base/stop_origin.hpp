// Who stopped the robot and how, and the sentence that says so to people (GET /api/estop's "summary", the dashboard's
// banner, rcanctl; docs/protocol.md §6.7).
#pragma once

#include <string>

namespace rcand {

struct StopOrigin {
  std::string principal;  // the credential's principal; empty when rcand itself or a plugin latched
  std::string kind;       // request | swarm | plugin | reload | startup | shutdown
  std::string from;       // where: the caller's words ("the dashboard"), the forwarding robot, the plugin
  std::string note;       // the caller's own reason; empty when it gave none
};

// "Stopped by dev-owner from the dashboard", "Stopped by plugin org.rcand.nav (nav): obstacle at 12 cm", "Latched at
// startup: ...". `reason` and `source` are the latch's own, for an origin of no known kind. No clock time: each
// reader shows since_ms in its own time zone.
std::string describe_stop(const StopOrigin& origin, const std::string& reason, const std::string& source);

}  // namespace rcand
