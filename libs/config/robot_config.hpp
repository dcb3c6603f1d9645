// The robot's `.rcan.yaml` file (docs/protocol.md §10), loaded, validated against one schema table and turned into typed
// settings.
#pragma once

#include <sys/types.h>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "libs/base/closest_match.hpp"
#include "libs/yaml/diagnostic.hpp"

namespace rcand::config {

using yaml::ConfigDiagnostic;
using yaml::ConfigError;
using yaml::SourceMark;

struct TokenEntry {
  std::string principal;
  std::string role;        // canonical upper-case role name ("OWNER"), whatever case the file used
  std::string sha256_hex;  // 64 lowercase hex chars: the SHA-256 of the token (plain tokens are never stored)
};

struct AuthConfig {
  std::string mode = "tokens";                           // "tokens" | "open"
  std::optional<std::filesystem::path> jwt_secret_file;  // absolute after loading
  std::vector<TokenEntry> tokens;
};

struct RuntimeConfig {
  std::string listen_address = "127.0.0.1";
  std::optional<std::uint16_t> listen_port;
  // runtime.listen.tls (paths absolute after loading) and the loopback plain port it comes with.
  struct ListenTls {
    std::filesystem::path cert_file, key_file;
    std::optional<std::filesystem::path> client_ca_file;
  };
  std::optional<ListenTls> listen_tls;
  std::optional<std::uint16_t> plain_loopback_port;
  std::vector<std::string> allowed_origins;  // runtime.listen.allowed_origins: other browser origins that may use the robot
  std::vector<std::filesystem::path> plugin_paths;  // absolute after loading
  AuthConfig auth;
  std::string log_level = "info";
  std::filesystem::path swarm_file = "/etc/rcand/swarm.yaml";  // absolute after loading (relative ones resolve like plugin_paths)
  int handler_timeout_ms = 10000;
  // HTTP connection limits: beyond them only the e-stop is served (503 SERVER_BUSY for the rest).
  std::size_t max_connections = 10000;
  std::size_t max_connections_per_address = 256;
  // Streamed answers (MJPEG viewers) held at once by one principal below OWNER, and by such principals from one
  // client address (everyone in auth mode open): docs/protocol.md §7.
  std::size_t max_streams_per_principal = 4;
  std::size_t max_streams_per_address = 8;
  int stop_path_priority = 10;          // SCHED_FIFO priority of the threads a stop runs on; 0 = leave them as they are
  int plugin_start_timeout_ms = 10000;  // a plugin's factory/start()/routes() that takes longer fails its instance
  std::optional<std::filesystem::path> audit_file;  // absolute after loading; every audit entry appended as a JSON line
  std::uint64_t audit_max_bytes = 64ull << 20;      // audit_file rotates past this size
  int audit_keep_files = 4;                         // rotated audit files kept
  // The e-stop latch record and the running marker (absolute after loading): runtime.state_dir, else
  // $STATE_DIRECTORY (its first entry), else /var/lib/rcand.
  std::filesystem::path state_dir = "/var/lib/rcand";
  // Request rate limits (docs/protocol.md §6.4); 0 = unlimited. The e-stop paths are never limited.
  double rate_limit_principal_per_s = 100;
  double rate_limit_address_per_s = 400;
  double rate_limit_burst_s = 2;
  nlohmann::json capabilities = nlohmann::json::object();  // name -> settings (a mapping; `name:` with no value gives {})
  nlohmann::json r2r = nlohmann::json::object();
};

struct DriverEntry {
  std::string id;
  std::string protocol;
  nlohmann::json settings;  // the whole entry, as written (validated later against the plugin's manifest)
  // The name the file gave when rcand read it as an alias (libs/config/driver_protocols.hpp): a plugin that provides
  // that name itself serves the driver instead (rcand picks it when it scans the plugins).
  std::string written_protocol = {};
};

struct RobotConfig {
  std::filesystem::path source_file;
  std::vector<std::filesystem::path> fragment_files;  // the conf.d fragments merged over it, in order
  nlohmann::json doc;                       // the whole document as JSON, defaults NOT filled in (what the operator wrote)
  std::map<std::string, SourceMark> marks;  // key path -> where it was written ("" is the document itself)
  std::string rcan_version;
  std::string robot_name, robot_uuid, manufacturer, model;
  std::optional<std::string> ruri;
  bool has_agent = false, has_camera = false;
  std::optional<double> wheel_circumference_m, turn_time_per_deg_s;
  double max_wheel_rps = 1.0;
  bool has_kinematics = false;
  std::vector<DriverEntry> drivers;
  std::uint16_t rcan_port = 8000;
  std::optional<std::vector<std::string>> capabilities;  // nullopt when the key is absent (auto-detect)
  bool enable_mdns = false, enable_jwt = true;
  bool estop_on_startup = false;
  RuntimeConfig runtime;
  std::uint16_t listen_port() const { return runtime.listen_port.value_or(rcan_port); }
  // Where `key_path` was written, or the nearest written ancestor's mark.
  SourceMark mark_of(std::string_view key_path) const;
  // A dotted key is set: present, not null, not false, not an empty list (a driver manifest's "implies" conditions).
  // physics.kinematics answers has_kinematics, so a config built in code reads the same.
  bool is_set(std::string_view dotted) const;
  // Whether the dotted key holds the boolean true (a manifest's "declared_when").
  bool is_true(std::string_view dotted) const;
};

struct LoadedConfig {
  RobotConfig config;
  std::vector<ConfigDiagnostic> warnings;
};

// How a file is judged. A config written for another runtime loads with warnings for what rcand supplies, reads
// differently or ignores (docs/protocol.md §10.3); `strict` (rcand --strict) makes every such warning an error, so
// only a file that says exactly what rcand runs is accepted.
//
// Trust: the file, its conf.d fragments, conf.d itself and the file's directory are refused (each named, with the
// chmod or chown that fixes it) when a user other than root or `user` could change them (libs/base/file_trust.hpp).
struct LoadOptions {
  bool strict = false;
  std::optional<uid_t> user = std::nullopt;  // whose files are trusted besides root's; unset: the user this process runs as
};
// The options every load uses unless it passes its own: rcand's main sets them once from the command line, so the
// start, --check-config and each SIGHUP reload judge a file alike.
void set_default_load_options(LoadOptions options) noexcept;
LoadOptions default_load_options() noexcept;

// A conf.d fragment (libs/config/config_fragments.hpp) as text, with the name its diagnostics use.
struct ConfigFragmentText {
  std::string text;
  std::string display_name;
};

// Throws ConfigError carrying every error found (a missing/unreadable file is one error with line 0). The fragments
// in conf.d/ beside `file` are merged over it first (config_fragments.hpp).
LoadedConfig load_robot_config(const std::filesystem::path& file, LoadOptions options = default_load_options());
// Same, from text; `display_name` is used in marks, `base_dir` resolves relative paths; `fragments` are merged over
// it in order.
LoadedConfig parse_robot_config(std::string_view yaml, const std::string& display_name, const std::filesystem::path& base_dir,
                                LoadOptions options = default_load_options(),
                                const std::vector<ConfigFragmentText>& fragments = {});

}  // namespace rcand::config
