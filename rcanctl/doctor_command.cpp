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
#include <iostream>
#include <optional>
#include <sstream>
#include <string_view>
#include <utility>
#include <vector>

#include "exit_codes.hpp"
#include "libs/mdns/service_browser.hpp"
#include "robot_connection.hpp"
#include "text_table.hpp"

namespace rcand::rcanctl {
namespace {

using nlohmann::json;

struct Finding {
  std::string check;
  bool ok = true;
  std::string detail;
  std::string fix;  // the command or step that fixes it, when not ok
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
  if (plugins.ok()) {
    std::size_t failed = 0;
    std::string which;
    for (const auto& plugin : plugins.body.value("plugins", json::array()))
      if (const auto state = plugin.value("state", std::string()); state != "loaded" && state != "installed-not-enabled") {
        ++failed;
        which += (which.empty() ? "" : ", ") + plugin.value("id", std::string("?")) + " (" +
                 plugin.value("state", std::string()) + ")";
      }
    out.push_back({"plugins", failed == 0, failed == 0 ? "all loaded" : which, "rcanctl plugins; sudo rcand --check-plugins"});
  }
  return out;
}

Finding mdns_finding() {
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
  constexpr std::string_view usage =
      "usage: rcanctl doctor [--config FILE] [--rcand PATH] [--as-user NAME] [--plugin-path DIR] [connection options]\n"
      "  checks the config (rcand --check-config, as NAME, default rcand when that user exists), the robot (answers,\n"
      "  state, e-stop, plugins), avahi-daemon and the clock; prints what is wrong and the command that fixes it.\n"
      "  --config default /etc/rcand/robot.rcan.yaml; --rcand default /usr/sbin/rcand. Exit 0 all well, 1 a problem.\n"
      "  connection: [--host HOST] [--port PORT] (--token T | --token-file FILE | $RCAND_TOKEN) [--json]\n";
  CheckArgs check{"/usr/sbin/rcand", "/etc/rcand/robot.rcan.yaml", "", ""};
  RobotOptions options;
  const ExtraOption extra = [&](const std::string& option, const std::function<bool(std::string&)>& next) {
    if (option == "--config") return next(check.config);
    if (option == "--rcand") return next(check.rcand);
    if (option == "--as-user") return next(check.user);
    if (option == "--plugin-path") return next(check.plugin_path);
    return false;
  };
  if (!parse_robot_options(args, "rcanctl doctor", extra, options, std::cerr)) {
    std::cerr << usage;
    return kExitUsage;
  }
  if (options.help) {
    std::cout << usage;
    return kExitOk;
  }
  if (check.user.empty() && ::getuid() == 0 && ::getpwnam("rcand") != nullptr) check.user = "rcand";  // the service's

  std::vector<Finding> findings{config_finding(check)};
  for (auto& finding : robot_findings(options)) findings.push_back(std::move(finding));
  findings.push_back(mdns_finding());
  findings.push_back(clock_finding());

  bool all_well = true;
  std::vector<std::vector<std::string>> rows{{"CHECK", "RESULT", "DETAIL", "FIX"}};
  for (const auto& f : findings) {
    all_well = all_well && f.ok;
    if (options.json)
      std::cout << json{{"check", f.check}, {"ok", f.ok}, {"detail", f.detail}, {"fix", f.ok ? json() : json(f.fix)}}.dump()
                << "\n";
    rows.push_back({f.check, f.ok ? "ok" : "PROBLEM", f.detail, f.ok ? "-" : f.fix});
  }
  if (!options.json) print_text_table(rows, std::cout);
  return all_well ? kExitOk : kExitFailure;
}

}  // namespace rcand::rcanctl
