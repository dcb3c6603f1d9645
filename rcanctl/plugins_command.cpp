#include "plugins_command.hpp"

#include <iostream>
#include <string_view>

#include "command_line.hpp"
#include "exit_codes.hpp"
#include "robot_connection.hpp"
#include "text_table.hpp"

namespace rcand::rcanctl {
namespace {

using nlohmann::json;

std::string cell(const json& value) {
  return value.is_string() ? value.get<std::string>() : value.is_null() ? "-" : value.dump();
}

}  // namespace

CLI::App* add_plugins_reload(CLI::App& plugins, std::string& id) {
  CLI::App* reload = plugins.add_subcommand(
      "reload",
      "Re-open plugin ID from disk in the running rcand (development robots): the e-stop is latched first (every\n"
      "motor halts) and stays latched; the plugin's routes answer 503 meanwhile. Needs an owner token and\n"
      "runtime.plugins.allow_reload: true in the robot's config (else 409 RELOAD_DISABLED).");
  reload->add_option("ID", id, "the plugin's id, e.g. org.rcand.teleop")->required();
  reload->footer(
      "--timeout defaults to 30000 here: a reload waits for in-flight calls and the plugin's shutdown and start.\n"
      "Exit: 0 reloaded, 1 the robot refused or the reload failed (code and reason on stderr; the plugin's state is\n"
      "printed either way), 2 usage.");
  return reload;
}

int run_plugins_reload(const std::string& id, const RobotOptions& options) {
  const RobotAnswer answer = call_robot(options, "POST", "/api/plugins/" + id + "/reload");
  const auto table = [&] {
    const json& b = answer.body;
    std::vector<std::vector<std::string>> rows{{"PLUGIN", "VERSION", "STATE", "KIND", "NAME", "INSTANCE", "REASON"}};
    for (const auto& instance : b.value("instances", json::array())) {
      const char* kind = instance.contains("driver") ? "driver" : "capability";
      rows.push_back({cell(b.value("plugin", json(id))), cell(b.value("version", json())), cell(b.value("state", json())), kind,
                      cell(instance.value(kind, json())), cell(instance.value("state", json())),
                      cell(instance.value("reason", json()))});
    }
    if (rows.size() == 1)
      rows.push_back({id, cell(b.value("version", json())), cell(b.value("state", json())), "-", "-", "-", "-"});
    print_text_table(rows, std::cout);
    if (b.value("estopped", false)) std::cout << "the e-stop is latched: clear it with `rcanctl estop clear`\n";
  };
  if (!answer.ok() && !options.json && answer.body.is_object() && answer.body.contains("state")) table();
  return report(options, answer, "plugins reload", table, std::cout, std::cerr);
}

}  // namespace rcand::rcanctl
