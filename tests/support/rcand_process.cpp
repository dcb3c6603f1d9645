#include "rcand_process.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <sstream>
#include <stdexcept>

#include "libs/rcan/crypto.hpp"
#include "libs/rcan/jwt.hpp"
#include "rcand/sdk/scope.hpp"

extern char** environ;

namespace rcand::test {
namespace fs = std::filesystem;

std::string rcand_binary() { return RCAND_BINARY; }
std::string rcanctl_binary() { return RCANCTL_BINARY; }
fs::path plugin_dir() { return RCAND_PLUGIN_DIR; }
fs::path test_plugin_dir() { return RCAND_TEST_PLUGIN_DIR; }

nlohmann::json sim_config() {
  using nlohmann::json;
  auto token = [](const char* principal, const char* role, const char* plain) {
    return json{{"principal", principal}, {"role", role}, {"sha256", rcand::sha256_hex(plain)}};
  };
  return {
      {"rcan_version", "1.3"},
      {"metadata",
       {{"robot_name", "test-rover"},
        {"robot_uuid", "1a2b3c4d-5e6f-4a5b-8c7d-9e0f1a2b3c4d"},
        {"manufacturer", "rcand"},
        {"model", "sim-rover"}}},
      {"physics", {{"wheel_circumference_m", 0.21}, {"turn_time_per_deg_s", 0.008}, {"max_wheel_rps", 1.0}}},
      {"drivers",
       json::array({{{"id", "drive0"}, {"protocol", "sim_diff_drive"}}, {{"id", "gripper0"}, {"protocol", "acme_gripper_sim"}}})},
      {"rcan_protocol", {{"port", 8000}, {"capabilities", {"status", "teleop", "com.acme.gripper"}}}},
      {"safety", {{"watchdog_ms", 500}}},
      {"runtime",
       {{"listen", {{"address", "127.0.0.1"}}},
        {"auth",
         {{"mode", "tokens"},
          {"jwt_secret_file", "jwt.secret"},
          {"tokens", json::array({token("owner-principal", "owner", "owner-token"), token("user-principal", "user", "user-token"),
                                  token("guest-principal", "guest", "guest-token")})}}},
        {"logging", {{"level", "info"}}},
        // Tests poll as fast as they can; the rate-limit tests turn the limits on themselves.
        {"rate_limit", {{"per_principal_per_s", 0}, {"per_address_per_s", 0}}}}},
  };
}

std::string jwt_for(const std::string& role, const std::string& secret) {
  rcand::JwtClaims claims;
  claims.sub = "test-" + role;
  claims.iss = "integration-test";
  claims.role = role;
  claims.aud = {"rcan://*"};
  const auto parsed_role = sdk::parse_role(role).value_or(sdk::Role::Guest);
  for (auto scope : {sdk::Scope::Status, sdk::Scope::Control, sdk::Scope::Config, sdk::Scope::Training, sdk::Scope::Admin})
    if (sdk::role_grants(parsed_role, scope)) claims.scope.emplace_back(sdk::scope_name(scope));
  claims.iat = std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  claims.exp = claims.iat + 3600;
  return rcand::issue_jwt_hs256(claims, secret);
}

namespace {

// RCAND_TEST_ISOLATE=vision,chat (ctest's *_isolated runs of a whole suite): those capabilities, where the config
// declares them, run with isolation: process unless the test itself chose.
void isolate_from_environment(nlohmann::json& config) {
  const char* names = std::getenv("RCAND_TEST_ISOLATE");
  if (names == nullptr || !config.is_object()) return;
  std::istringstream list(names);
  for (std::string name; std::getline(list, name, ',');) {
    auto& settings = config["runtime"]["capabilities"][name];
    if (settings.is_null()) settings = nlohmann::json::object();
    if (settings.is_object() && !settings.contains("isolation")) settings["isolation"] = "process";
  }
}

struct Spawned {
  pid_t pid = -1;
  int stdout_fd = -1;
  int stdin_fd = -1;
};

// posix_spawn with stdout (and optionally stdin) on pipes and stderr to a file.
Spawned spawn(const std::string& binary, const std::vector<std::string>& args, const fs::path& stderr_file, bool with_stdin) {
  int out[2], in[2] = {-1, -1};
  if (pipe2(out, O_CLOEXEC) != 0) throw std::runtime_error("pipe failed");
  if (with_stdin && pipe2(in, O_CLOEXEC) != 0) throw std::runtime_error("pipe failed");
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
  if (with_stdin) posix_spawn_file_actions_adddup2(&actions, in[0], STDIN_FILENO);
  else posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, stderr_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  std::vector<char*> argv{const_cast<char*>(binary.c_str())};
  for (const auto& arg : args) argv.push_back(const_cast<char*>(arg.c_str()));
  argv.push_back(nullptr);
  Spawned result;
  const int rc = posix_spawn(&result.pid, binary.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  close(out[1]);
  if (with_stdin) close(in[0]);
  if (rc != 0) {
    close(out[0]);
    if (with_stdin) close(in[1]);
    throw std::runtime_error("cannot start " + binary + ": " + std::strerror(rc));
  }
  result.stdout_fd = out[0];
  result.stdin_fd = in[1];
  return result;
}

std::string slurp(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// In a sanitizer build (ASan/UBSan options inherited through environ) a child's report must fail the test even when
// the test never looks at the child's exit status (a leak reported at exit, say): print it and abort the test.
void abort_on_sanitizer_report(const std::string& who, const std::string& err) {
  for (const char* marker :
       {"ERROR: AddressSanitizer", "ERROR: LeakSanitizer", "SUMMARY: UndefinedBehaviorSanitizer", ": runtime error: "}) {
    if (err.find(marker) == std::string::npos) continue;
    std::cerr << "\n==== " << who << " reported a sanitizer error; its stderr:\n" << err << "\n==== failing the test\n";
    std::abort();
  }
}

int wait_exit(pid_t pid) {
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

}  // namespace

ProcessResult run_tool(const std::string& binary, const std::vector<std::string>& args, const std::string& stdin_text,
                       std::chrono::milliseconds limit) {
  TempDir scratch;
  const auto err_file = scratch.path() / "stderr";
  auto child = spawn(binary, args, err_file, true);
  if (!stdin_text.empty()) {
    if (::write(child.stdin_fd, stdin_text.data(), stdin_text.size()) < 0) {
    }
  }
  close(child.stdin_fd);
  ProcessResult result;
  std::array<char, 4096> buffer;
  const auto deadline = std::chrono::steady_clock::now() + limit;
  bool killed = false;
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (!killed && left.count() <= 0) {
      ::kill(child.pid, SIGKILL);  // its stdout closes with it
      killed = true;
    }
    pollfd ready{child.stdout_fd, POLLIN, 0};
    if (::poll(&ready, 1, killed ? -1 : static_cast<int>(left.count()) + 1) <= 0) continue;  // EINTR, or the deadline
    const ssize_t n = ::read(child.stdout_fd, buffer.data(), buffer.size());
    if (n == 0 || (n < 0 && errno != EINTR)) break;
    if (n > 0) result.out.append(buffer.data(), static_cast<std::size_t>(n));
  }
  close(child.stdout_fd);
  result.exit_code = wait_exit(child.pid);
  result.err = slurp(err_file);
  abort_on_sanitizer_report(binary, result.err);
  if (killed) result.err += "\n(run_tool: still running after " + std::to_string(limit.count()) + " ms: killed)\n";
  return result;
}

RcandProcess::RcandProcess(const nlohmann::json& config, std::vector<fs::path> plugin_paths, Ready ready) {
  launch(config, std::move(plugin_paths), {}, ready);
}

RcandProcess::RcandProcess(const nlohmann::json& config, std::vector<std::string> launcher, std::string host)
    : host_(std::move(host)) {
  launch(config, {}, launcher);
}

void RcandProcess::launch(const nlohmann::json& config, std::vector<fs::path> plugin_paths,
                          const std::vector<std::string>& launcher, Ready wanted) {
  dir_.write("jwt.secret", kJwtSecret);
  // Hermetic: a state dir of this process's own (inside its temp dir) unless the test names one (to share it
  // between two processes in turn, say); never the system's /var/lib/rcand.
  nlohmann::json effective = config;
  if (effective.is_object() && effective.contains("runtime") && effective["runtime"].is_object() &&
      !effective["runtime"].contains("state_dir"))
    effective["runtime"]["state_dir"] = (dir_.path() / "state").string();
  isolate_from_environment(effective);
  const auto config_file = dir_.write("robot.rcan.yaml", effective.dump(2));
  // The build tree's plugins, unless the test names its own directories (as arguments or in the config).
  const bool config_names_plugins = effective.is_object() && effective.contains("runtime") && effective["runtime"].is_object() &&
                                    effective["runtime"].contains("plugin_paths");
  if (plugin_paths.empty() && !config_names_plugins) plugin_paths.push_back(plugin_dir());
  std::vector<std::string> args{"--config", config_file.string(), "--port", "0"};
  for (const auto& path : plugin_paths) {
    args.emplace_back("--plugin-path");
    args.push_back(path.string());
  }
  if (!launcher.empty()) {
    args.insert(args.begin(), rcand_binary());
    args.insert(args.begin(), launcher.begin() + 1, launcher.end());
  }
  auto child = spawn(launcher.empty() ? rcand_binary() : launcher.front(), args, dir_.path() / "stderr", false);
  pid_ = child.pid;
  stdout_fd_ = child.stdout_fd;

  // Wait for the ready line (and the capabilities' one: it may come first): an event on the pipe, with a generous
  // deadline only against a hung start.
  constexpr std::string_view kReady = "rcand: listening on http://";
  constexpr std::string_view kCapabilitiesStarted = "rcand: capabilities started\n";
  std::string text;
  std::size_t ready = std::string::npos;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while ((ready = text.find(kReady)) == std::string::npos || text.find('\n', ready) == std::string::npos ||
         (wanted == Ready::CapabilitiesStarted && text.find(kCapabilitiesStarted) == std::string::npos)) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    pollfd fd{stdout_fd_, POLLIN, 0};
    if (left.count() <= 0 || poll(&fd, 1, static_cast<int>(left.count())) <= 0) break;
    char chunk[256];
    const ssize_t n = ::read(stdout_fd_, chunk, sizeof chunk);
    if (n <= 0) break;  // rcand exited
    text.append(chunk, static_cast<std::size_t>(n));
  }
  const std::string line = ready == std::string::npos ? "" : text.substr(ready, text.find('\n', ready) - ready);
  const auto colon = line.rfind(':');
  if (line.empty() || colon == std::string::npos) {
    const std::string err = stderr_text();
    stop();
    throw std::runtime_error("rcand did not start:\n" + text + err);
  }
  port_ = static_cast<std::uint16_t>(std::stoi(line.substr(colon + 1)));
  // runtime.listen.tls: "rcand: listening on https://ADDRESS:PORT" comes first, then the loopback plain port's line.
  if (const auto tls = text.find("rcand: listening on https://"); tls != std::string::npos && tls < ready) {
    const std::string tls_line = text.substr(tls, text.find('\n', tls) - tls);
    tls_port_ = static_cast<std::uint16_t>(std::stoi(tls_line.substr(tls_line.rfind(':') + 1)));
  }
}

RcandProcess::~RcandProcess() { stop(); }

int RcandProcess::stop() {
  if (pid_ <= 0) return -1;
  kill(pid_, SIGTERM);
  // Wait for the exit as an event (a pidfd becomes readable), bounded, then SIGKILL: no process is left behind.
  int status = 0;
  if (const int pidfd = static_cast<int>(syscall(SYS_pidfd_open, pid_, 0)); pidfd >= 0) {
    pollfd exited{pidfd, POLLIN, 0};
    poll(&exited, 1, 15000);
    close(pidfd);
  }
  if (waitpid(pid_, &status, WNOHANG) == 0) {
    kill(pid_, SIGKILL);
    waitpid(pid_, &status, 0);
  }
  pid_ = -1;
  if (stdout_fd_ >= 0) close(stdout_fd_);
  stdout_fd_ = -1;
  abort_on_sanitizer_report("rcand", stderr_text());
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

int RcandProcess::kill_hard() {
  if (pid_ <= 0) return -1;
  kill(pid_, SIGKILL);
  int status = 0;
  while (waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
  }
  pid_ = -1;
  if (stdout_fd_ >= 0) close(stdout_fd_);
  stdout_fd_ = -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::string RcandProcess::stderr_text() const { return slurp(dir_.path() / "stderr"); }

http::ClientResponse RcandProcess::request(const std::string& method, const std::string& target, const std::string& token,
                                           const std::string& body, std::map<std::string, std::string> headers) const {
  if (!token.empty()) headers["Authorization"] = "Bearer " + token;
  return http::request(host_, port_, method, target, body, headers, std::chrono::seconds(10));
}

nlohmann::json RcandProcess::json(const std::string& method, const std::string& target, const std::string& token,
                                  const std::string& body, int* status) const {
  const auto response = request(method, target, token, body);
  if (status) *status = response.status;
  return nlohmann::json::parse(response.body, nullptr, false);
}

long resident_kb(pid_t pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(status, line);)
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  return -1;
}

std::size_t count_of(const std::string& text, const std::string& needle) {
  std::size_t n = 0;
  for (auto at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1)) ++n;
  return n;
}

}  // namespace rcand::test
