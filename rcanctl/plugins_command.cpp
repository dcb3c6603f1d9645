#include "plugins_command.hpp"

#include <iostream>
#include <string_view>

#include "exit_codes.hpp"
#include "robot_connection.hpp"
#include "text_table.hpp"

namespace rcand::rcanctl {
namespace {

using nlohmann::json;

constexpr std::string_view kReloadUsage =
    "usage: rcanctl plugins reload ID   re-open plugin ID from disk in the running rcand (development robots):\n"
    "  the e-stop is latched first (every motor halts) and stays latched; the plugin's routes answer 503 meanwhile.\n"
    "  Needs an owner token and runtime.plugins.allow_reload: true in the robot's config (else 409 RELOAD_DISABLED).\n"
    "  connection: [--host HOST] [--port PORT] (--token T | --token-file FILE | $RCAND_TOKEN) [--json] [--timeout MS]\n"
    "  (--timeout defaults to 30000 here: a reload waits for in-flight calls and the plugin's shutdown and start).\n"
    "  Exit: 0 reloaded, 1 the robot refused or the reload failed (code and reason on stderr; the plugin's state\n"
    "  is printed either way), 2 usage.\n";

std::string cell(const json& value) {
  return value.is_string() ? value.get<std::string>() : value.is_null() ? "-" : value.dump();
}

}  // namespace

int run_plugins_reload(std::span<const std::string> args) {
  std::string id;
  RobotOptions options;
  options.timeout = std::chrono::milliseconds(30000);
  const ExtraOption positional = [&](const std::string& word, const std::function<bool(std::string&)>&) {
    if (!id.empty() || word.starts_with("-")) return false;
    id = word;
    return true;
  };
  if (!parse_robot_options(args, "rcanctl plugins reload", positional, options, std::cerr) || (id.empty() && !options.help)) {
    if (id.empty() && !options.help) std::cerr << "rcanctl plugins reload: the plugin ID is required\n";
    std::cerr << kReloadUsage;
    return kExitUsage;
  }
  if (options.help) {
    std::cout << kReloadUsage;
    return kExitOk;
  }
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
