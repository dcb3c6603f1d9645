#include "instance_problems.hpp"

#include <ostream>

namespace rcand::rcanctl {
namespace {

using nlohmann::json;

std::string string_field(const json& object, const char* key) {
  if (!object.is_object() || !object.contains(key) || !object[key].is_string()) return {};
  return object[key].get<std::string>();
}

// One instance item (a driver of /api/status, a capability's entry, or an /api/plugins instance); nothing when ok.
void add_problem(const json& item, std::string kind, std::string name, std::vector<InstanceProblem>& problems) {
  const std::string state = string_field(item, "state");
  if (state.empty() || state == "ok") return;
  std::string reason = string_field(item, "reason");
  const std::string device = string_field(item, "device");
  if (!device.empty() && reason.find(device) == std::string::npos) {  // the reason usually names it already
    const std::string os_error = string_field(item, "os_error");
    reason += (reason.empty() ? "" : " (") + device + (os_error.empty() ? "" : ": " + os_error) + (reason.empty() ? "" : ")");
  }
  problems.push_back({std::move(kind), std::move(name), state, std::move(reason), string_field(item, "hint")});
}

}  // namespace

json InstanceProblem::to_json() const {
  json object{{kind, name}, {"state", state}, {"reason", reason}};
  if (!hint.empty()) object["hint"] = hint;
  return object;
}

std::string InstanceProblem::summary() const { return kind + " " + name + " " + state + (reason.empty() ? "" : ": " + reason); }

std::vector<InstanceProblem> status_problems(const json& status) {
  std::vector<InstanceProblem> problems;
  if (!status.is_object()) return problems;
  if (status.contains("drivers") && status["drivers"].is_array())
    for (const auto& driver : status["drivers"]) add_problem(driver, "driver", string_field(driver, "id"), problems);
  if (status.contains("capabilities") && status["capabilities"].is_object())
    for (const auto& [name, capability] : status["capabilities"].items()) add_problem(capability, "capability", name, problems);
  return problems;
}

std::vector<InstanceProblem> plugin_problems(const json& plugin) {
  std::vector<InstanceProblem> problems;
  if (!plugin.is_object() || !plugin.contains("instances") || !plugin["instances"].is_array()) return problems;
  for (const auto& instance : plugin["instances"]) {
    const char* kind = instance.contains("driver") ? "driver" : "capability";
    add_problem(instance, kind, string_field(instance, kind), problems);
  }
  return problems;
}

void print_problems(const std::vector<InstanceProblem>& problems, const std::string& indent, std::ostream& out) {
  for (const auto& problem : problems) {
    out << indent << problem.summary() << "\n";
    if (!problem.hint.empty()) out << indent << "  fix: " << problem.hint << "\n";
  }
}

}  // namespace rcand::rcanctl
