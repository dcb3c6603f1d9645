// What is wrong with a robot's driver and capability instances, for people: the robot's GET /api/status (drivers[],
// capabilities{}) and GET /api/plugins (plugins[].instances[]) carry each instance's state with its reason, the
// device, the OS error and a hint (docs/protocol.md §7.2, §7.14). rcanctl status, plugins and doctor print them, so
// the fix ("is the U2D2 plugged in?") is on the operator's screen, not only in the JSON and the log.
#pragma once

#include <nlohmann/json.hpp>

#include <iosfwd>
#include <string>
#include <vector>

namespace rcand::rcanctl {

struct InstanceProblem {
  std::string kind;    // "driver" or "capability"
  std::string name;    // arm0, teleop
  std::string state;   // failed, error, degraded
  std::string reason;  // "cannot open /dev/ttyUSB0: No such file or directory"
  std::string hint;    // "is the U2D2 plugged in? ..."; "" when the robot gave none
  nlohmann::json to_json() const;
  std::string summary() const;  // "driver arm0 failed: cannot open /dev/ttyUSB0: No such file or directory"
};

// Every instance not "ok" in a GET /api/status body: drivers first (a capability usually fails because of one).
std::vector<InstanceProblem> status_problems(const nlohmann::json& status);

// Every instance not "ok" of one GET /api/plugins item.
std::vector<InstanceProblem> plugin_problems(const nlohmann::json& plugin);

// "  <summary>\n    fix: <hint>\n" per problem, each line after `indent`.
void print_problems(const std::vector<InstanceProblem>& problems, const std::string& indent, std::ostream& out);

}  // namespace rcand::rcanctl
