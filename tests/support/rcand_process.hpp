// Integration-test support: a real rcand process on loopback with a config of the test's own, in a temporary
// directory the fixture removes. The process is ready when it prints its "listening on" line (read from a pipe,
// no sleeping); it is stopped with SIGTERM (SIGKILL if it does not exit) and always reaped.
#pragma once

#include <sys/types.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "libs/http/client.hpp"
#include "temp_dir.hpp"

namespace rcand::test {

// The bundled sim robot's config as JSON (JSON is YAML), with test credentials: a JWT secret and pre-shared tokens
// "owner-token", "user-token", "guest-token". Tests edit it before starting rcand.
nlohmann::json sim_config();
inline constexpr const char* kJwtSecret = "integration-test-secret-0123456789abcdef";

// A JWT for `role` signed with kJwtSecret (or `secret`), valid for an hour, aud "rcan://*".
std::string jwt_for(const std::string& role, const std::string& secret = kJwtSecret);

struct ProcessResult {
  int exit_code = -1;
  std::string out, err;
};
// Runs rcand (or rcanctl) to completion with `args`; for --check-config, --check-plugins, --version, and starts
// expected to be refused. One still running after `limit` (an rcand that serves where a refusal was expected) is
// killed (exit_code 128+9), so such a test fails instead of hanging.
ProcessResult run_tool(const std::string& binary, const std::vector<std::string>& args, const std::string& stdin_text = {},
                       std::chrono::milliseconds limit = std::chrono::seconds(120));
std::string rcand_binary();
std::string rcanctl_binary();
// The in-tree plugin directory, and the fixture plugins' directory.
std::filesystem::path plugin_dir();
std::filesystem::path test_plugin_dir();

class RcandProcess {
 public:
  // Writes `config` to <tmp>/robot.rcan.yaml (plus the JWT secret file) and starts rcand on port 0 loading plugins
  // only from `plugin_paths` (default: the build tree's). Without runtime.state_dir in `config`, the state dir is
  // <tmp>/state (hermetic); set it to a directory of the test's to share it between processes run in turn.
  // Throws std::runtime_error with rcand's stderr when it does not come up. Returns once every capability is up or
  // failed ("rcand: capabilities started"), or with Ready::Serving as soon as rcand serves (capabilities may still be
  // starting then: 503 STARTING).
  enum class Ready { CapabilitiesStarted, Serving };
  explicit RcandProcess(const nlohmann::json& config, std::vector<std::filesystem::path> plugin_paths = {},
                        Ready ready = Ready::CapabilitiesStarted);
  // The same started through `launcher` (e.g. {"ip", "netns", "exec", "ns1"}: rcand inside a network namespace),
  // reached at `host` (the config's runtime.listen.address there).
  RcandProcess(const nlohmann::json& config, std::vector<std::string> launcher, std::string host);
  ~RcandProcess();
  RcandProcess(const RcandProcess&) = delete;
  RcandProcess& operator=(const RcandProcess&) = delete;

  // The plain HTTP port (with runtime.listen.tls: the loopback plain port), and the TLS port (0 without TLS).
  std::uint16_t port() const noexcept { return port_; }
  std::uint16_t tls_port() const noexcept { return tls_port_; }
  const std::string& host() const noexcept { return host_; }
  pid_t pid() const noexcept { return pid_; }
  const TempDir& dir() const noexcept { return dir_; }

  // One request on a fresh connection; `token` becomes "Authorization: Bearer <token>" when non-empty.
  http::ClientResponse request(const std::string& method, const std::string& target, const std::string& token = {},
                               const std::string& body = {}, std::map<std::string, std::string> headers = {}) const;
  // request() with the body parsed as JSON (null when it is not JSON).
  nlohmann::json json(const std::string& method, const std::string& target, const std::string& token = {},
                      const std::string& body = {}, int* status = nullptr) const;
  // SIGTERM and wait; returns the exit status (or 128+signal).
  int stop();
  // SIGKILL (no clean shutdown: a crash as far as rcand's state dir is concerned) and reap; returns 128+9.
  int kill_hard();
  std::string stderr_text() const;

 private:
  TempDir dir_;
  pid_t pid_ = -1;
  int stdout_fd_ = -1;
  std::uint16_t port_ = 0;
  std::uint16_t tls_port_ = 0;
  std::string host_ = "127.0.0.1";
  void launch(const nlohmann::json& config, std::vector<std::filesystem::path> plugin_paths,
              const std::vector<std::string>& launcher, Ready ready = Ready::CapabilitiesStarted);
};

// The resident memory of `pid` in kB (VmRSS), -1 when it cannot be read.
long resident_kb(pid_t pid);
// How many times `needle` occurs in `text` (log lines, say).
std::size_t count_of(const std::string& text, const std::string& needle);

// The sim drive's status as the robot reports it (GET /api/drivers/drive0, as the owner).
inline nlohmann::json drive_status(const RcandProcess& robot) {
  return robot.json("GET", "/api/drivers/drive0", "owner-token")["status"];
}

}  // namespace rcand::test
