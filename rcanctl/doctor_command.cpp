#include "doctor_command.hpp"

#include <fcntl.h>
#include <pwd.h>
#include <spawn.h>
#include <sys/timex.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <string_view>
#include <utility>
#include <vector>

#include "command_line.hpp"
#include "exit_codes.hpp"
#include "instance_problems.hpp"
#include "libs/config/config_fragments.hpp"
#include "libs/mdns/service_browser.hpp"
#include "libs/yaml/yaml_document.hpp"
#include "robot_connection.hpp"
#include "text_table.hpp"

namespace rcand::rcanctl {
namespace {

using nlohmann::json;

struct Finding {
  std::string check;
  bool ok = true;
  std::string detail;
  std::string fix;       // the command or step that fixes it, when not ok
  bool skipped = false;  // the config does not use what it checks
};

struct CheckArgs {
  std::string rcand, config, user, plugin_path;
};

// `word` as one word of a POSIX shell command, so a fix with any path can be pasted as it is: unchanged when it has
// only characters no shell treats specially, else in single quotes (a quote inside written '\'').
std::string shell_word(const std::string& word) {
  constexpr std::string_view kPlain = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-./:=@%+,";
  if (!word.empty() && word.find_first_not_of(kPlain) == std::string::npos) return word;
  std::string quoted = "'";
  for (char c : word) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return quoted + "'";
}

// Runs `argv` (no shell: any path works as given) with stdout and stderr on one pipe: its wait status and output,
// or nullopt (errno set) when it could not be started.
std::optional<std::pair<int, std::string>> run_captured(const std::vector<std::string>& argv) {
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) return std::nullopt;
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);  // the copies lose O_CLOEXEC
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDERR_FILENO);
  std::vector<char*> args;
  for (const auto& arg : argv) args.push_back(const_cast<char*>(arg.c_str()));
  args.push_back(nullptr);
  pid_t pid = 0;
  const int spawned = ::posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  ::close(fds[1]);
  std::string output;
  if (spawned == 0) {
    char chunk[4096];
    for (ssize_t n; (n = ::read(fds[0], chunk, sizeof chunk)) != 0;) {
      if (n > 0) output.append(chunk, static_cast<std::size_t>(n));
      else if (errno != EINTR) break;
    }
  }
  ::close(fds[0]);
  if (spawned != 0) {
    errno = spawned;  // posix_spawn returns the error instead of setting errno
    return std::nullopt;
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return std::pair{status, std::move(output)};
}

// `rcand --check-config`, run as a child (its verdict is the daemon's own); the first error line, or nullopt when OK.
std::optional<std::string> check_config(const CheckArgs& a) {
  std::vector<std::string> argv{a.rcand, "--check-config", a.config};
  if (!a.user.empty()) argv.insert(argv.end(), {"--as-user", a.user});
  if (!a.plugin_path.empty()) argv.insert(argv.end(), {"--plugin-path", a.plugin_path});
  const auto run = run_captured(argv);
  if (!run) return "cannot run " + a.rcand + ": " + std::strerror(errno);
  if (run->first == 0) return std::nullopt;
  std::istringstream lines(run->second);
  for (std::string line; std::getline(lines, line);)
    if (line.find("error") != std::string::npos || line.find("--as-user") != std::string::npos) return line;
  return "rcand --check-config failed";
}

Finding config_finding(const CheckArgs& a) {
  Finding f{"config", true, a.config + " is valid" + (a.user.empty() ? "" : " and usable by " + a.user), ""};
  if (!std::filesystem::exists(a.config))
    return {"config", false, a.config + " does not exist",
            "sudo apt install --reinstall -o Dpkg::Options::=--force-confmiss rcand (restores the packaged one)"};
  if (const auto problem = check_config(a)) {
    f.ok = false;
    f.detail = *problem;
    f.fix = "edit " + shell_word(a.config) + ", then: sudo " + shell_word(a.rcand) + " --check-config " + shell_word(a.config) +
            (a.user.empty() ? "" : " --as-user " + shell_word(a.user));
  }
  return f;
}

Finding plugins_finding(const json& answer);

std::vector<Finding> robot_findings(const RobotOptions& options) {
  const std::string where = options.host + ":" + std::to_string(options.port);
  const auto status = call_robot(options, "GET", "/api/status");
  if (status.status == 0)
    return {
        {"robot", false, "no answer at " + where + ": " + status.error, "sudo systemctl start rcand; journalctl -u rcand -e"}};
  if (!status.ok())
    return {{"robot", false, where + " answered: " + status.error, "check the token: rcanctl token new / --token"}};
  std::vector<Finding> out;
  const std::string state = status.body.value("state", std::string("?"));
  out.push_back(
      {"robot", state != "error", where + " is " + state, "rcanctl plugins (what failed), then: sudo systemctl restart rcand"});
  const auto estop = call_robot(options, "GET", "/api/estop");
  if (estop.ok() && estop.body.value("estopped", false))
    out.push_back({"e-stop", false, "latched: " + estop.body.value("reason", std::string()),
                   "rcanctl estop clear (owner token), once it is safe"});
  else if (estop.ok()) out.push_back({"e-stop", true, "not latched", ""});
  const auto plugins = call_robot(options, "GET", "/api/plugins");
  if (plugins.ok()) out.push_back(plugins_finding(plugins.body));
  return out;
}

// A library that did not load, or one whose driver or capability instance failed or is in error ("health", §7.2):
// a loaded plugin whose driver failed is not ok. The detail names each instance and why; the fix is the robot's hint.
Finding plugins_finding(const json& answer) {
  std::string which, hints;
  for (const auto& plugin : answer.value("plugins", json::array())) {
    const std::string id = plugin.value("id", std::string("?"));
    const std::string state = plugin.value("state", std::string());
    if (state != "loaded" && state != "installed-not-enabled") {
      which += (which.empty() ? "" : "; ") + id + " (" + state + ")";
      continue;
    }
    const std::string health = plugin.value("health", std::string("ok"));
    if (health != "error" && health != "degraded") continue;
    for (const auto& problem : plugin_problems(plugin)) {
      which += (which.empty() ? "" : "; ") + id + ": " + problem.summary();
      if (!problem.hint.empty() && hints.find(problem.hint) == std::string::npos)
        hints += (hints.empty() ? "" : "; ") + problem.hint;
    }
  }
  if (which.empty()) return {"plugins", true, "all loaded, every instance ok", ""};
  return {"plugins", false, which,
          (hints.empty() ? "" : hints + "; then ") + "sudo systemctl restart rcand (rcanctl plugins lists every instance)"};
}

// Whether the robot's config (with its conf.d fragments, as rcand merges them) turns mDNS on; nullopt when it
// cannot be read (the config check says why).
std::optional<bool> config_enables_mdns(const std::string& config_file) {
  std::vector<yaml::ConfigDiagnostic> diagnostics;
  const auto read = [&](const std::filesystem::path& file) {
    std::ifstream in(file);
    std::stringstream text;
    text << in.rdbuf();
    return in ? yaml::yaml_to_json(text.str(), file.string(), diagnostics) : yaml::YamlDocument{};
  };
  yaml::YamlDocument config = read(config_file);
  if (!config.ok) return std::nullopt;
  for (const auto& fragment_file : config::config_fragment_files(config_file))
    if (const auto fragment = read(fragment_file); fragment.ok)
      config::merge_config_fragment(config, fragment, fragment_file.string(), diagnostics);
  const json enabled = config.doc.value("/rcan_protocol/enable_mdns"_json_pointer, json(false));
  return enabled == true;
}

Finding mdns_finding(const std::string& config_file) {
  // A check of something the config does not use is skipped, not failed (the bundled robot has mDNS off).
  if (config_enables_mdns(config_file) == false)
    return {"mDNS", true, "skipped: rcan_protocol.enable_mdns is off in " + config_file, "", true};
  const auto browse = mdns::browse_services("_rcan._tcp", std::chrono::milliseconds(1500));
  if (!browse.error.empty())
    return {"mDNS", false, browse.error, "sudo apt install avahi-daemon && sudo systemctl enable --now avahi-daemon"};
  return {"mDNS", true, std::to_string(browse.services.size()) + " robot(s) seen on the LAN", ""};
}

Finding clock_finding() {
  timex tx{};
  const int state = ::adjtimex(&tx);
  const bool synced = state != TIME_ERROR && (tx.status & STA_UNSYNC) == 0;
  return {"clock", synced, synced ? "synchronised (NTP)" : "not synchronised: JWT expiry and R2R timestamps drift",
          "sudo timedatectl set-ntp true"};
}

}  // namespace

int run_doctor(std::span<const std::string> args) {
  CheckArgs check{"/usr/sbin/rcand", "/etc/rcand/robot.rcan.yaml", "", ""};
  RobotOptions options;
  const auto app = make_command_app(
      "rcanctl doctor",
      "Checks the config (rcand --check-config), the robot (answers, state, e-stop, plugins and their instances),\n"
      "avahi-daemon (when the config turns mDNS on) and the clock; prints what is wrong and the command that fixes it.",
      "Exit: 0 all well, 1 a problem, 2 usage.");
  app->add_option("--config", check.config, "the robot's config (default /etc/rcand/robot.rcan.yaml)");
  app->add_option("--rcand", check.rcand, "the rcand binary that checks it (default /usr/sbin/rcand)");
  app->add_option("--as-user", check.user, "check the config as this user (default rcand when run as root and it exists)");
  app->add_option("--plugin-path", check.plugin_path, "where rcand finds its plugins (default its own)");
  add_robot_options(*app, options);
  if (auto done = parse_robot_command(*app, args, options)) return *done;
  if (check.user.empty() && ::getuid() == 0 && ::getpwnam("rcand") != nullptr) check.user = "rcand";  // the service's

  std::vector<Finding> findings{config_finding(check)};
  for (auto& finding : robot_findings(options)) findings.push_back(std::move(finding));
  findings.push_back(mdns_finding(check.config));
  findings.push_back(clock_finding());

  bool all_well = true;
  std::vector<std::vector<std::string>> rows{{"CHECK", "RESULT", "DETAIL", "FIX"}};
  for (const auto& f : findings) {
    all_well = all_well && f.ok;
    if (options.json) {
      json line{{"check", f.check}, {"ok", f.ok}, {"detail", f.detail}, {"fix", f.ok ? json() : json(f.fix)}};
      if (f.skipped) line["skipped"] = true;
      std::cout << line.dump() << "\n";
    }
    rows.push_back({f.check, f.skipped ? "skipped" : f.ok ? "ok" : "PROBLEM", f.detail, f.ok ? "-" : f.fix});
  }
  if (!options.json) print_text_table(rows, std::cout);
  return all_well ? kExitOk : kExitFailure;
}

}  // namespace rcand::rcanctl
