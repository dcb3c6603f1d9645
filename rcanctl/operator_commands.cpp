#include "operator_commands.hpp"

#include <poll.h>
#include <unistd.h>

#include <atomic>
#include <charconv>
#include <chrono>
#include <cmath>
#include <csignal>
#include <iostream>
#include <optional>
#include <string_view>
#include <thread>

#include "exit_codes.hpp"
#include "plugins_command.hpp"
#include "robot_connection.hpp"
#include "text_table.hpp"

namespace rcand::rcanctl {
namespace {

using nlohmann::json;

constexpr std::string_view kConnectionUsage =
    "  connection: [--host HOST] [--port PORT] (--token T | --token-file FILE | $RCAND_TOKEN) [--json] [--timeout MS]\n"
    "  HOST default 127.0.0.1, PORT default 8000. Exit: 0 done, 1 the robot refused or did not answer, 2 usage.\n";

std::optional<double> parse_double(const std::string& text) {
  double value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc{} || end != text.data() + text.size()) return std::nullopt;
  return value;
}

// A numeric option's value into `into`; false after the usage error.
bool number_option(const std::string& option, const std::function<bool(std::string&)>& next, std::optional<double>& into) {
  std::string text;
  if (!next(text)) return false;
  into = parse_double(text);
  if (!into) std::cerr << "rcanctl: " << option << " must be a number, got '" << text << "'\n";
  return into.has_value();
}

// Parses the connection options plus `extra`; prints usage on error (exit 2) or for --help (exit 0).
std::optional<int> parse(std::span<const std::string> args, std::string_view name, std::string_view usage,
                         const ExtraOption& extra, RobotOptions& options) {
  const std::string prefix = "rcanctl " + std::string(name);
  if (!parse_robot_options(args, prefix, extra, options, std::cerr)) {
    std::cerr << usage << kConnectionUsage;
    return kExitUsage;
  }
  if (options.help) {
    std::cout << usage << kConnectionUsage;
    return kExitOk;
  }
  return std::nullopt;
}

std::string text(const json& value) {
  if (value.is_null()) return "-";
  return value.is_string() ? value.get<std::string>() : value.dump();
}

// The first word when it is a verb (not an option), else `fallback`.
std::string verb_of(std::span<const std::string>& args, std::string fallback) {
  if (args.empty() || args.front().starts_with("-")) return fallback;
  std::string verb = args.front();
  args = args.subspan(1);
  return verb;
}

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
  constexpr std::string_view usage =
      "usage: rcanctl estop [show]   the e-stop: latched or not, since when, why, by whom\n"
      "       rcanctl estop clear    clear it (needs the config scope: an owner token)\n";
  const std::string verb = verb_of(args, "show");
  RobotOptions options;
  if (auto done = parse(args, "estop", usage, {}, options)) return *done;
  if (verb != "show" && verb != "clear") {
    std::cerr << "rcanctl estop: unknown action '" << verb << "'\n" << usage;
    return kExitUsage;
  }
  const auto answer = verb == "clear" ? call_robot(options, "POST", "/api/estop/clear", json::object())
                                      : call_robot(options, "GET", "/api/estop");
  return report(
      options, answer, "estop " + verb,
      [&] {
        if (verb == "clear") std::cout << "e-stop cleared\n";
        else if (!answer.body.value("estopped", false)) std::cout << "not latched\n";
        else
          std::cout << "LATCHED since " << text(answer.body["since_ms"]) << " ms: " << text(answer.body["reason"]) << " (by "
                    << text(answer.body["source"]) << ")\n";
      },
      std::cout, std::cerr);
}

int run_move(std::span<const std::string> args) {
  constexpr std::string_view usage =
      "usage: rcanctl move [--linear X] [--angular Y] [--duration MS | --hold]\n"
      "  a teleop move: linear in [-1, 1] of full speed (or safety.max_linear_speed), angular in [-1, 1]; the one left\n"
      "  out is 0. --duration stops it after MS; --hold keeps moving until Enter, end of input or Ctrl-C, then stops\n"
      "  (each move lasts 500 ms, so a lost rcanctl stops the robot within that).\n";
  std::optional<double> linear, angular, duration;
  bool hold = false;
  RobotOptions options;
  const ExtraOption extra = [&](const std::string& option, const std::function<bool(std::string&)>& next) {
    if (option == "--linear") return number_option(option, next, linear);
    if (option == "--angular") return number_option(option, next, angular);
    if (option == "--duration") return number_option(option, next, duration);
    if (option == "--hold") return hold = true;
    return false;
  };
  if (auto done = parse(args, "move", usage, extra, options)) return *done;
  if (!linear && !angular) {
    std::cerr << "rcanctl move: --linear or --angular is required\n" << usage;
    return kExitUsage;
  }
  if (duration && (*duration != std::floor(*duration) || std::abs(*duration) > 1e9)) {
    std::cerr << "rcanctl move: --duration must be whole milliseconds\n" << usage;
    return kExitUsage;
  }
  json move{{"type", "move"}, {"linear", linear.value_or(0.0)}, {"angular", angular.value_or(0.0)}};
  if (duration) move["duration_ms"] = static_cast<long long>(*duration);  // the robot checks the range
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
  constexpr std::string_view usage =
      "usage: rcanctl nav go --distance M [--heading DEG] [--speed S]   start a waypoint job (turn, then drive)\n"
      "       rcanctl nav status                                       the job and the pose\n"
      "       rcanctl nav cancel                                       stop the job\n";
  const std::string verb = verb_of(args, "");
  std::optional<double> distance, heading, speed;
  RobotOptions options;
  const ExtraOption extra = [&](const std::string& option, const std::function<bool(std::string&)>& next) {
    if (verb != "go") return false;
    if (option == "--distance") return number_option(option, next, distance);
    if (option == "--heading") return number_option(option, next, heading);
    if (option == "--speed") return number_option(option, next, speed);
    return false;
  };
  if (auto done = parse(args, "nav", usage, extra, options)) return *done;
  if (verb == "go") {
    if (!distance) {
      std::cerr << "rcanctl nav go: --distance is required\n" << usage;
      return kExitUsage;
    }
    json waypoint{{"distance_m", *distance}, {"heading_deg", heading.value_or(0.0)}};
    if (speed) waypoint["speed"] = *speed;
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
  std::cerr << "rcanctl nav: " << (verb.empty() ? "an action is required" : "unknown action '" + verb + "'") << "\n" << usage;
  return kExitUsage;
}

int run_plugins(std::span<const std::string> args) {
  constexpr std::string_view usage =
      "usage: rcanctl plugins   every plugin found: version, state, what it provides, why it failed\n"
      "       rcanctl plugins reload ID   re-open one plugin from disk (development robots; plugins reload --help)\n";
  if (!args.empty() && args.front() == "reload") return run_plugins_reload(args.subspan(1));
  RobotOptions options;
  if (auto done = parse(args, "plugins", usage, {}, options)) return *done;
  const auto answer = call_robot(options, "GET", "/api/plugins");
  return report(
      options, answer, "plugins",
      [&] {
        std::vector<std::vector<std::string>> rows{{"ID", "VERSION", "STATE", "PROVIDES", "REASON"}};
        for (const auto& plugin : answer.body.value("plugins", json::array())) {
          std::string provides;
          for (const auto& item : plugin.value("provides", json::array()))
            provides +=
                (provides.empty() ? "" : ",") + item.value("kind", std::string()) + ":" + item.value("name", std::string());
          const std::string reason = plugin.value("reason", std::string());
          rows.push_back({text(plugin.value("id", json())), text(plugin.value("version", json())),
                          text(plugin.value("state", json())), provides.empty() ? "-" : provides, reason.empty() ? "-" : reason});
        }
        print_text_table(rows, std::cout);
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
  constexpr std::string_view usage =
      "usage: rcanctl audit [--limit N] [--follow]   the newest N audit entries (default 20), oldest first;\n"
      "  --follow keeps printing new ones (once a second) until Ctrl-C. Needs the config scope (an owner token).\n";
  std::optional<double> limit;
  bool follow = false;
  RobotOptions options;
  const ExtraOption extra = [&](const std::string& option, const std::function<bool(std::string&)>& next) {
    if (option == "--limit") return number_option(option, next, limit);
    if (option == "--follow") return follow = true;
    return false;
  };
  if (auto done = parse(args, "audit", usage, extra, options)) return *done;
  const int count = limit ? static_cast<int>(*limit) : 20;
  if (count < 1 || count > 10000) {
    std::cerr << "rcanctl audit: --limit must be from 1 to 10000\n";
    return kExitUsage;
  }
  std::signal(SIGINT, on_release_signal);
  std::uint64_t last_seq = 0;
  bool header = !options.json;
  for (;;) {
    const auto answer = call_robot(options, "GET", "/api/audit?limit=" + std::to_string(count));
    if (!answer.ok())
      return report(
          options, answer, "audit", [] {}, std::cout, std::cerr);
    std::vector<std::vector<std::string>> rows;
    if (header) rows.push_back({"SEQ", "TIME_MS", "PRINCIPAL", "EVENT", "OUTCOME", "DETAIL"});
    header = false;
    const json entries = answer.body.value("entries", json::array());
    for (auto it = entries.rbegin(); it != entries.rend(); ++it) {  // the robot sends newest first
      const auto seq = it->value("seq", std::uint64_t{0});
      if (seq <= last_seq) continue;
      last_seq = seq;
      if (options.json) std::cout << it->dump(-1, ' ', false, json::error_handler_t::replace) << "\n";
      else
        rows.push_back({text(it->value("seq", json())), text(it->value("timestamp_ms", json())),
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
