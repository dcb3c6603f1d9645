#include "operator_commands.hpp"

#include <poll.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <iostream>
#include <optional>
#include <string_view>
#include <thread>

#include "command_line.hpp"
#include "exit_codes.hpp"
#include "human_format.hpp"
#include "instance_problems.hpp"
#include "plugins_command.hpp"
#include "robot_connection.hpp"
#include "text_table.hpp"

namespace rcand::rcanctl {
namespace {

using nlohmann::json;

std::string text(const json& value) { return human_text(value); }

std::atomic<bool> released{false};
extern "C" void on_release_signal(int) { released.store(true); }

// Hold-to-move: true once the operator lets go (Enter, end of input, Ctrl-C), polled every `period`.
bool wait_released(std::chrono::milliseconds period) {
  pollfd in{STDIN_FILENO, POLLIN, 0};
  if (::poll(&in, 1, static_cast<int>(period.count())) > 0) return true;  // a key, or end of input
  return released.load();
}

}  // namespace

int run_estop(std::span<const std::string> args) {
  RobotOptions options;
  const auto app = make_command_app("rcanctl estop", "The e-stop: latched or not, since when, why, by whom; or clear it.",
                                    "Exit: 0 done, 1 the robot refused or did not answer, 2 usage.");
  CLI::App* show = app->add_subcommand("show", "the e-stop's state (the default)");
  CLI::App* clear = app->add_subcommand("clear", "clear the latch (needs the config scope: an owner token)");
  app->require_subcommand(0, 1);
  for (CLI::App* each : {app.get(), show, clear}) add_robot_options(*each, options);
  if (auto done = parse_robot_command(*app, args, options)) return *done;
  const std::string verb = clear->parsed() ? "clear" : "show";
  const auto answer = verb == "clear" ? call_robot(options, "POST", "/api/estop/clear", json::object())
                                      : call_robot(options, "GET", "/api/estop");
  return report(
      options, answer, "estop " + verb,
      [&] {
        if (verb == "clear") std::cout << "e-stop cleared\n";
        else if (!answer.body.value("estopped", false)) std::cout << "not latched\n";
        else
          std::cout << "LATCHED since " << human_time(answer.body["since_ms"]) << ": " << text(answer.body["reason"]) << " (by "
                    << text(answer.body["source"]) << ")\n";
      },
      std::cout, std::cerr);
}

int run_move(std::span<const std::string> args) {
  double linear = 0, angular = 0;
  int duration = 0;
  bool hold = false;
  RobotOptions options;
  const auto app = make_command_app(
      "rcanctl move",
      "A teleop move: --linear and --angular in [-1, 1] of full speed (or safety.max_linear_speed); the one left out\n"
      "is 0. --duration stops it after MS; --hold keeps moving until Enter, end of input or Ctrl-C, then stops (each\n"
      "move lasts 500 ms, so a lost rcanctl stops the robot within that).",
      "Exit: 0 done, 1 the robot refused or did not answer, 2 usage.");
  auto* linear_option = app->add_option("--linear", linear, "forward speed, -1 to 1")->check(finite_number());
  auto* angular_option = app->add_option("--angular", angular, "turning speed, -1 to 1")->check(finite_number());
  auto* duration_option = app->add_option("--duration", duration, "stop after MS milliseconds (whole)");
  app->add_flag("--hold", hold, "keep moving until Enter, end of input or Ctrl-C")->excludes(duration_option);
  add_robot_options(*app, options);
  if (auto done = parse_robot_command(*app, args, options)) return *done;
  if (linear_option->count() == 0 && angular_option->count() == 0)
    return usage_error(*app, "--linear or --angular is required", std::cerr);
  json move{{"type", "move"}, {"linear", linear}, {"angular", angular}};
  if (duration_option->count() > 0) move["duration_ms"] = duration;  // the robot checks the range
  if (!hold) {
    const auto answer = call_robot(options, "POST", "/api/action", move);
    return report(
        options, answer, "move", [&] { std::cout << "moving: " << answer.body.dump() << "\n"; }, std::cout, std::cerr);
  }
  constexpr auto kRefresh = std::chrono::milliseconds(200);
  move["duration_ms"] = 500;
  std::signal(SIGINT, on_release_signal);
  std::signal(SIGTERM, on_release_signal);
  if (!options.json) std::cerr << "moving; press Enter (or Ctrl-C) to stop\n";
  RobotAnswer answer;
  do {
    answer = call_robot(options, "POST", "/api/action", move);
  } while (answer.ok() && !wait_released(kRefresh));
  const auto stop = call_robot(options, "POST", "/api/action", json{{"type", "stop"}});
  if (!answer.ok())
    return report(
        options, answer, "move", [] {}, std::cout, std::cerr);
  return report(
      options, stop, "move", [] { std::cout << "released: stopped\n"; }, std::cout, std::cerr);
}

int run_nav(std::span<const std::string> args) {
  double distance = 0, heading = 0, speed = 0;
  RobotOptions options;
  const auto app = make_command_app("rcanctl nav", "Waypoint jobs of the nav capability.",
                                    "Exit: 0 done, 1 the robot refused or did not answer, 2 usage.");
  CLI::App* go = app->add_subcommand("go", "start a waypoint job: turn to --heading, then drive --distance");
  go->add_option("--distance", distance, "metres to drive")->required()->check(finite_number());
  go->add_option("--heading", heading, "degrees to turn first (default 0)")->check(finite_number());
  auto* speed_option = go->add_option("--speed", speed, "speed, 0 to 1 of full (default the robot's)")->check(finite_number());
  CLI::App* status = app->add_subcommand("status", "the job and the pose");
  CLI::App* cancel = app->add_subcommand("cancel", "stop the job");
  app->require_subcommand(1);
  for (CLI::App* each : {go, status, cancel}) add_robot_options(*each, options);
  if (auto done = parse_robot_command(*app, args, options)) return *done;
  const std::string verb = app->get_subcommands().front()->get_name();
  if (verb == "go") {
    json waypoint{{"distance_m", distance}, {"heading_deg", heading}};
    if (speed_option->count() > 0) waypoint["speed"] = speed;
    const auto answer = call_robot(options, "POST", "/api/nav/waypoint", waypoint);
    return report(
        options, answer, "nav go",
        [&] { std::cout << "job " << text(answer.body["job_id"]) << " started, eta " << text(answer.body["eta_ms"]) << " ms\n"; },
        std::cout, std::cerr);
  }
  if (verb == "cancel") {
    const auto answer = call_robot(options, "POST", "/api/nav/cancel", json::object());
    return report(
        options, answer, "nav cancel",
        [&] { std::cout << (answer.body.value("cancelled", false) ? "job cancelled\n" : "no job was running\n"); }, std::cout,
        std::cerr);
  }
  if (verb == "status") {
    const auto answer = call_robot(options, "GET", "/api/nav/status");
    return report(
        options, answer, "nav status",
        [&] {
          const json& b = answer.body;
          const json pose = b.value("pose", json::object());
          print_text_table({{"JOB", "STATE", "DISTANCE", "HEADING", "ELAPSED", "ETA", "RESULT", "POSE"},
                            {text(b.value("job_id", json())), text(b.value("state", json())), text(b.value("distance_m", json())),
                             text(b.value("heading_deg", json())), text(b.value("elapsed_ms", json())),
                             text(b.value("eta_ms", json())), text(b.value("result", json())),
                             text(pose.value("x_m", json())) + "," + text(pose.value("y_m", json())) + " @" +
                                 text(pose.value("heading_deg", json()))}},
                           std::cout);
        },
        std::cout, std::cerr);
  }
  return usage_error(*app, "unknown action '" + verb + "'", std::cerr);
}

int run_plugins(std::span<const std::string> args) {
  RobotOptions options;
  std::string reload_id;
  const auto app = make_command_app(
      "rcanctl plugins",
      "Every plugin found and each of its driver and capability instances: version, library state, health, each\n"
      "instance's state and why one failed, and the fix the robot suggests.",
      "Exit: 0 listed, 1 the robot refused or did not answer, 2 usage.");
  CLI::App* reload = add_plugins_reload(*app, reload_id);
  app->require_subcommand(0, 1);
  for (CLI::App* each : {app.get(), reload}) add_robot_options(*each, options);
  if (auto done = parse_robot_command(*app, args, options)) return *done;
  if (reload->parsed()) {
    // A reload waits for in-flight calls and the plugin's shutdown and start.
    if (reload->count("--timeout") == 0 && app->count("--timeout") == 0) options.timeout = std::chrono::milliseconds(30000);
    return run_plugins_reload(reload_id, options);
  }
  const auto answer = call_robot(options, "GET", "/api/plugins");
  return report(
      options, answer, "plugins",
      [&] {
        // One row per instance (a loaded library whose driver failed is not ok), the library's own when it has none;
        // the fixes the robot suggests under the table.
        std::vector<std::vector<std::string>> rows{{"ID", "VERSION", "LIBRARY", "HEALTH", "INSTANCE", "STATE", "REASON"}};
        std::vector<InstanceProblem> problems;
        for (const auto& plugin : answer.body.value("plugins", json::array())) {
          const std::vector<std::string> library{text(plugin.value("id", json())), text(plugin.value("version", json())),
                                                 text(plugin.value("state", json())), text(plugin.value("health", json()))};
          const std::string library_reason = plugin.value("reason", std::string());
          const json instances = plugin.value("instances", json::array());
          if (instances.empty()) {
            rows.push_back(library);
            rows.back().insert(rows.back().end(), {"-", "-", library_reason.empty() ? "-" : library_reason});
          }
          for (const auto& instance : instances) {
            const char* kind = instance.contains("driver") ? "driver" : "capability";
            const std::string reason = instance.value("reason", library_reason);
            rows.push_back(library);
            rows.back().insert(rows.back().end(), {std::string(kind) + ":" + text(instance.value(kind, json())),
                                                   text(instance.value("state", json())), reason.empty() ? "-" : reason});
          }
          for (auto& problem : plugin_problems(plugin))
            if (!problem.hint.empty()) problems.push_back(std::move(problem));
        }
        print_text_table(rows, std::cout);
        if (!problems.empty()) std::cout << "\n";
        print_problems(problems, "", std::cout);
      },
      std::cout, std::cerr);
}

// An entry's event; a stop repeated while latched is one entry (docs/protocol.md §6.3): "POST /api/stop (x2000)".
static std::string audit_event_text(const json& entry) {
  std::string event = text(entry.value("event", json()));
  if (const auto count = entry.value("count", std::uint64_t{1}); count > 1) event += " (x" + std::to_string(count) + ")";
  return event;
}

int run_audit(std::span<const std::string> args) {
  int count = 20;
  bool follow = false;
  RobotOptions options;
  const auto app =
      make_command_app("rcanctl audit", "The newest audit entries, oldest first. Needs the config scope (an owner token).",
                       "Exit: 0 done, 1 the robot refused or did not answer, 2 usage.");
  app->add_option("--limit", count, "how many entries (default 20)")->check(CLI::Range(1, 10000));
  app->add_flag("--follow", follow, "keep printing new ones (once a second) until Ctrl-C");
  add_robot_options(*app, options);
  if (auto done = parse_robot_command(*app, args, options)) return *done;
  std::signal(SIGINT, on_release_signal);
  std::uint64_t last_seq = 0;
  bool header = !options.json;
  for (;;) {
    const auto answer = call_robot(options, "GET", "/api/audit?limit=" + std::to_string(count));
    if (!answer.ok())
      return report(
          options, answer, "audit", [] {}, std::cout, std::cerr);
    std::vector<std::vector<std::string>> rows;
    if (header) rows.push_back({"SEQ", "TIME", "PRINCIPAL", "EVENT", "OUTCOME", "DETAIL"});
    header = false;
    const json entries = answer.body.value("entries", json::array());
    for (auto it = entries.rbegin(); it != entries.rend(); ++it) {  // the robot sends newest first
      const auto seq = it->value("seq", std::uint64_t{0});
      if (seq <= last_seq) continue;
      last_seq = seq;
      if (options.json) std::cout << it->dump(-1, ' ', false, json::error_handler_t::replace) << "\n";
      else
        rows.push_back({text(it->value("seq", json())), human_time(it->value("timestamp_ms", json())),
                        text(it->value("principal", json())), audit_event_text(*it), text(it->value("outcome", json())),
                        text(it->value("detail", json()))});
    }
    if (rows.size() > 0) print_text_table(rows, std::cout);
    std::cout.flush();
    if (!follow) return kExitOk;
    for (int tick = 0; tick < 10 && !released.load(); ++tick) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (released.load()) return kExitOk;
  }
}

}  // namespace rcand::rcanctl
