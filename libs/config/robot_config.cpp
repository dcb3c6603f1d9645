#include "libs/config/robot_config.hpp"

#include "libs/base/file_trust.hpp"
#include "libs/config/config_defaults.hpp"
#include "libs/config/config_fragments.hpp"
#include "libs/config/config_schema.hpp"
#include "libs/config/foreign_shapes.hpp"
#include "libs/rcan/machine_identity.hpp"
#include "libs/yaml/yaml_document.hpp"

#include <rcand/sdk/scope.hpp>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <tuple>

namespace rcand::config {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;
using detail::schema_default;

// Far larger than any hand-written config; keeps a wrong path (a disk image, /dev/zero) from exhausting memory.
constexpr std::size_t kMaxFileBytes = 4 * 1024 * 1024;

[[noreturn]] void fail_file(const std::string& file, std::string message) {
  throw ConfigError({ConfigDiagnostic{ConfigDiagnostic::Severity::Error, SourceMark{file, 0, 0}, "", std::move(message)}});
}

// Damerau (optimal string alignment) distance, case-insensitive: a swapped pair of letters is one typo.
const json* find(const json& doc, std::string_view dotted) {
  const json* node = &doc;
  while (!dotted.empty()) {
    const auto dot = dotted.find('.');
    if (!node->is_object()) return nullptr;
    const auto it = node->find(std::string(dotted.substr(0, dot)));
    if (it == node->end()) return nullptr;
    node = &*it;
    dotted = dot == std::string_view::npos ? std::string_view{} : dotted.substr(dot + 1);
  }
  return node;
}

// The value the operator wrote, else the schema table's default: the table is the one place defaults live.
template <class T> T value_or_default(const json& doc, std::string_view path) {
  const json* node = find(doc, path);
  if (node != nullptr && !node->is_null()) return node->get<T>();
  return schema_default(path).get<T>();
}

template <class T> std::optional<T> optional_value(const json& doc, std::string_view path) {
  const json* node = find(doc, path);
  if (node == nullptr || node->is_null()) return std::nullopt;
  return node->get<T>();
}

fs::path resolve(const fs::path& base_dir, const std::string& text) {
  fs::path path(text);
  if (path.is_relative()) path = base_dir / path;
  return path.lexically_normal();
}

json object_or_empty(const json* node) { return node != nullptr && node->is_object() ? *node : json::object(); }

// Runs only on a document that passed validation, so every type below is known to be right.
// The runtime: block: rcand's own settings (listen address, auth, limits, files), paths resolved against the file.
RuntimeConfig extract_runtime(const json& doc, const fs::path& base_dir) {
  RuntimeConfig r;
  r.listen_address = value_or_default<std::string>(doc, "runtime.listen.address");
  if (const auto port = optional_value<std::int64_t>(doc, "runtime.listen.port"))
    r.listen_port = static_cast<std::uint16_t>(*port);
  if (const auto cert_file = optional_value<std::string>(doc, "runtime.listen.tls.cert_file")) {
    auto& tls = r.listen_tls.emplace();
    tls.cert_file = resolve(base_dir, *cert_file);
    tls.key_file = resolve(base_dir, optional_value<std::string>(doc, "runtime.listen.tls.key_file").value_or(""));
    if (const auto ca_file = optional_value<std::string>(doc, "runtime.listen.tls.client_ca_file"))
      tls.client_ca_file = resolve(base_dir, *ca_file);
  }
  if (const auto plain_port = optional_value<std::int64_t>(doc, "runtime.listen.plain_loopback_port"))
    r.plain_loopback_port = static_cast<std::uint16_t>(*plain_port);
  if (const json* origins = find(doc, "runtime.listen.allowed_origins"); origins != nullptr && origins->is_array())
    for (const auto& origin : *origins) r.allowed_origins.push_back(origin.get<std::string>());
  if (const json* paths = find(doc, "runtime.plugin_paths"); paths != nullptr && paths->is_array())
    for (const auto& path : *paths) r.plugin_paths.push_back(resolve(base_dir, path.get<std::string>()));
  r.auth.mode = value_or_default<std::string>(doc, "runtime.auth.mode");
  if (const auto secret_file = optional_value<std::string>(doc, "runtime.auth.jwt_secret_file"))
    r.auth.jwt_secret_file = resolve(base_dir, *secret_file);
  if (const json* tokens = find(doc, "runtime.auth.tokens"); tokens != nullptr && tokens->is_array()) {
    for (const auto& token : *tokens) {
      const auto role = sdk::parse_role(token.at("role").get<std::string>()).value();  // validated by the schema
      r.auth.tokens.push_back(TokenEntry{token.at("principal").get<std::string>(), std::string(sdk::role_name(role)),
                                         token.at("sha256").get<std::string>()});
    }
  }
  r.log_level = value_or_default<std::string>(doc, "runtime.logging.level");
  r.swarm_file = resolve(base_dir, value_or_default<std::string>(doc, "runtime.swarm_file"));
  r.handler_timeout_ms = static_cast<int>(value_or_default<std::int64_t>(doc, "runtime.handler_timeout_ms"));
  r.stop_path_priority = static_cast<int>(value_or_default<std::int64_t>(doc, "runtime.stop_path_priority"));
  r.max_connections = static_cast<std::size_t>(value_or_default<std::int64_t>(doc, "runtime.max_connections"));
  r.max_connections_per_address =
      static_cast<std::size_t>(value_or_default<std::int64_t>(doc, "runtime.max_connections_per_address"));
  r.max_streams_per_principal =
      static_cast<std::size_t>(value_or_default<std::int64_t>(doc, "runtime.max_streams_per_principal"));
  r.max_streams_per_address = static_cast<std::size_t>(value_or_default<std::int64_t>(doc, "runtime.max_streams_per_address"));
  r.plugin_start_timeout_ms = static_cast<int>(value_or_default<std::int64_t>(doc, "runtime.plugin_start_timeout_ms"));
  if (const json* audit_file = find(doc, "runtime.audit_file"); audit_file != nullptr && audit_file->is_string())
    r.audit_file = resolve(base_dir, audit_file->get<std::string>());
  r.audit_max_bytes = static_cast<std::uint64_t>(value_or_default<std::int64_t>(doc, "runtime.audit_max_bytes"));
  r.audit_keep_files = static_cast<int>(value_or_default<std::int64_t>(doc, "runtime.audit_keep_files"));
  if (const auto state_dir = optional_value<std::string>(doc, "runtime.state_dir")) {
    r.state_dir = resolve(base_dir, *state_dir);
  } else if (const char* systemd = std::getenv("STATE_DIRECTORY"); systemd != nullptr && *systemd != '\0') {
    const std::string first(systemd, std::strcspn(systemd, ":"));  // systemd lists several, colon-separated
    if (!first.empty()) r.state_dir = first;
  }
  r.rate_limit_principal_per_s = value_or_default<double>(doc, "runtime.rate_limit.per_principal_per_s");
  r.rate_limit_address_per_s = value_or_default<double>(doc, "runtime.rate_limit.per_address_per_s");
  r.rate_limit_burst_s = value_or_default<double>(doc, "runtime.rate_limit.burst_s");
  r.capabilities = json::object();
  if (const json* caps = find(doc, "runtime.capabilities"); caps != nullptr && caps->is_object())
    for (const auto& [name, settings] : caps->items()) r.capabilities[name] = object_or_empty(&settings);
  r.r2r = object_or_empty(find(doc, "runtime.r2r"));
  return r;
}

std::size_t hex_digits(std::string_view text) {
  return static_cast<std::size_t>(std::count_if(text.begin(), text.end(), [](unsigned char c) { return std::isxdigit(c) != 0; }));
}

RobotConfig extract(yaml::YamlDocument yaml, const fs::path& source_file, const fs::path& base_dir,
                    std::vector<ConfigDiagnostic>& warnings) {
  RobotConfig c;
  c.source_file = source_file;
  c.doc = std::move(yaml.doc);
  c.marks = std::move(yaml.marks);
  const json& doc = c.doc;

  c.rcan_version = value_or_default<std::string>(doc, "rcan_version");
  c.robot_name = value_or_default<std::string>(doc, "metadata.robot_name");
  c.robot_uuid = optional_value<std::string>(doc, "metadata.robot_uuid").value_or("");
  c.manufacturer = optional_value<std::string>(doc, "metadata.manufacturer").value_or("");
  c.model = optional_value<std::string>(doc, "metadata.model").value_or("");
  c.ruri = optional_value<std::string>(doc, "metadata.ruri");
  // RCAN §1: the device id is 8 hex digits or a UUID; a name ("bob-001") would make every such robot 00000000.
  const bool not_an_id = !c.robot_uuid.empty() && hex_digits(c.robot_uuid) < 8;
  if (!c.ruri && not_an_id)
    warnings.push_back({ConfigDiagnostic::Severity::Warning, c.mark_of("metadata.robot_uuid"), "metadata.robot_uuid",
                        "not a UUID or 8 hex digits (RCAN §1): this robot's identity is derived from /etc/machine-id "
                        "instead"});
  if (!c.ruri && (c.robot_uuid.empty() || not_an_id || is_placeholder_uuid(c.robot_uuid))) {  // one packaged config, many robots
    const auto derived = robot_uuid_from_machine_id();
    if (!derived)
      throw ConfigError({{ConfigDiagnostic::Severity::Error, c.mark_of("metadata.robot_uuid"), "metadata.robot_uuid",
                          "not set (or the all-zero placeholder), and /etc/machine-id cannot be read to derive one: "
                          "give this robot its own UUID"}});
    c.robot_uuid = *derived;
  }

  c.has_agent = doc.contains("agent");
  c.has_camera = doc.contains("camera");

  c.wheel_circumference_m = optional_value<double>(doc, "physics.wheel_circumference_m");
  c.turn_time_per_deg_s = optional_value<double>(doc, "physics.turn_time_per_deg_s");
  c.max_wheel_rps = value_or_default<double>(doc, "physics.max_wheel_rps");
  const json* kinematics = find(doc, "physics.kinematics");
  c.has_kinematics = kinematics != nullptr && kinematics->is_array() && !kinematics->empty();

  if (const json* drivers = find(doc, "drivers"); drivers != nullptr && drivers->is_array())
    for (const auto& entry : *drivers)
      c.drivers.push_back(DriverEntry{entry.value("id", ""), entry.at("protocol").get<std::string>(), entry});

  c.rcan_port = static_cast<std::uint16_t>(value_or_default<std::int64_t>(doc, "rcan_protocol.port"));
  c.capabilities = optional_value<std::vector<std::string>>(doc, "rcan_protocol.capabilities");
  c.enable_mdns = value_or_default<bool>(doc, "rcan_protocol.enable_mdns");
  c.enable_jwt = value_or_default<bool>(doc, "rcan_protocol.enable_jwt");

  c.estop_on_startup = value_or_default<bool>(doc, "safety.estop_on_startup");

  c.runtime = extract_runtime(doc, base_dir);
  apply_config_defaults(c, warnings);
  return c;
}

std::atomic<bool> default_strict{false};

// By file (the main file's name sorts apart from conf.d's), then line and column.
void sort_by_position(std::vector<ConfigDiagnostic>& diagnostics) {
  std::stable_sort(diagnostics.begin(), diagnostics.end(), [](const ConfigDiagnostic& a, const ConfigDiagnostic& b) {
    return std::tie(a.mark.file, a.mark.line, a.mark.column) < std::tie(b.mark.file, b.mark.line, b.mark.column);
  });
}

ConfigDiagnostic refusal(const std::string& file, const std::string& what, const std::string& problem) {
  return ConfigDiagnostic{ConfigDiagnostic::Severity::Error, SourceMark{file, 0, 0}, "",
                          "refused: " + what + " that a user other than root or rcand's own could change: " + problem};
}

// The file's text, read through the descriptor its owner and mode were checked on (no swap between check and read).
// One that another user could change is added to `refused` (docs/protocol.md §10.5); one that cannot be read at
// all throws.
std::string read_config_text(const fs::path& file, uid_t user, std::vector<ConfigDiagnostic>& refused) {
  const std::string display = file.string();
  const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0)
    fail_file(display, errno == ENOENT ? std::string("cannot read the config file: no such file")
                                       : std::string("cannot read the config file: ") + std::strerror(errno));
  struct stat info {};
  std::string text, error;
  if (::fstat(fd, &info) != 0) error = std::string("cannot read the config file: ") + std::strerror(errno);
  else if (S_ISDIR(info.st_mode)) error = "cannot read the config file: it is a directory";
  char buffer[64 * 1024];
  for (ssize_t n = 0; error.empty() && (n = ::read(fd, buffer, sizeof buffer)) != 0;) {
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) error = std::string("cannot read the config file: ") + std::strerror(errno);
    else text.append(buffer, static_cast<std::size_t>(n));
    if (text.size() > kMaxFileBytes)
      error = "the config file is larger than " + std::to_string(kMaxFileBytes / (1024 * 1024)) + " MiB";
  }
  ::close(fd);
  if (!error.empty()) fail_file(display, error);
  if (auto problem = untrusted_writers(file, info, user); !problem.empty())
    refused.push_back(refusal(display, "a config file", problem));
  return text;
}

// --strict: every warning refuses the file, each named at its own position.
[[noreturn]] void refuse_strictly(std::vector<ConfigDiagnostic> warnings) {
  for (auto& diagnostic : warnings) {
    diagnostic.severity = ConfigDiagnostic::Severity::Error;
    diagnostic.message += " [refused: --strict]";
  }
  throw ConfigError(std::move(warnings));
}

}  // namespace

SourceMark RobotConfig::mark_of(std::string_view key_path) const {
  return yaml::nearest_mark(marks, source_file.string(), std::string(key_path));
}

bool RobotConfig::is_set(std::string_view dotted) const {
  if (dotted == "physics.kinematics") return has_kinematics;  // the loader's own reading of it
  const json* value = find(doc, dotted);
  return value != nullptr && !value->is_null() && *value != false && !(value->is_array() && value->empty());
}

bool RobotConfig::is_true(std::string_view dotted) const {
  const json* value = find(doc, dotted);
  return value != nullptr && value->is_boolean() && value->get<bool>();
}

void set_default_load_options(LoadOptions options) noexcept { default_strict.store(options.strict); }
LoadOptions default_load_options() noexcept { return LoadOptions{default_strict.load()}; }

LoadedConfig parse_robot_config(std::string_view yaml, const std::string& display_name, const fs::path& base_dir,
                                LoadOptions options, const std::vector<ConfigFragmentText>& fragments) {
  std::vector<ConfigDiagnostic> diagnostics;
  yaml::YamlDocument document = yaml::yaml_to_json(yaml, display_name, diagnostics);
  for (const auto& fragment : fragments) {
    std::vector<ConfigDiagnostic> found;
    const yaml::YamlDocument patch = yaml::yaml_to_json(fragment.text, fragment.display_name, found);
    if (patch.empty) continue;  // nothing in it, or only comments: it changes nothing
    diagnostics.insert(diagnostics.end(), found.begin(), found.end());
    if (document.ok && patch.ok) merge_config_fragment(document, patch, fragment.display_name, diagnostics);
  }
  if (document.ok) read_foreign_shapes(document, display_name, diagnostics);
  if (document.ok) detail::validate_config(document.doc, document.marks, display_name, diagnostics);
  const auto error_found = [&diagnostics] {
    return std::any_of(diagnostics.begin(), diagnostics.end(),
                       [](const ConfigDiagnostic& d) { return d.severity == ConfigDiagnostic::Severity::Error; });
  };
  // The files the keys name are read only once the keys themselves are right.
  if (document.ok && !error_found())
    detail::check_fragment_files(document.doc, document.marks, display_name, base_dir, diagnostics);
  sort_by_position(diagnostics);
  const bool has_error = std::any_of(diagnostics.begin(), diagnostics.end(),
                                     [](const ConfigDiagnostic& d) { return d.severity == ConfigDiagnostic::Severity::Error; });
  if (has_error || !document.ok) throw ConfigError(std::move(diagnostics));

  std::error_code ec;
  fs::path base = fs::absolute(base_dir, ec);
  if (ec) base = base_dir;
  LoadedConfig loaded;
  try {
    loaded.config = extract(std::move(document), display_name, base, diagnostics);
  } catch (const ConfigError&) {
    throw;
  } catch (const std::exception& e) {
    // Validation should make this unreachable; if the table and the extraction ever disagree, fail cleanly.
    fail_file(display_name, std::string("internal error while reading the validated config: ") + e.what());
  }
  sort_by_position(diagnostics);
  if (options.strict && !diagnostics.empty()) refuse_strictly(std::move(diagnostics));
  loaded.warnings = std::move(diagnostics);
  return loaded;
}

LoadedConfig load_robot_config(const fs::path& file, LoadOptions options) {
  // As sshd's StrictModes: nothing another user could have written is loaded, the directories that decide which
  // files are read included (one who can write conf.d adds a fragment; a sticky directory keeps our file ours).
  const uid_t user = options.user.value_or(::geteuid());
  std::vector<ConfigDiagnostic> refused;
  const std::string text = read_config_text(file, user, refused);
  std::error_code ec;
  const fs::path absolute = fs::absolute(file, ec);
  const fs::path source = ec ? file : absolute.lexically_normal();
  if (auto problem = untrusted_writers(source.parent_path(), user, true); !problem.empty())
    refused.push_back(refusal(source.parent_path().string(), "the config file's directory", problem));
  if (const fs::path conf_d = source.parent_path() / "conf.d"; fs::is_directory(conf_d, ec))
    if (auto problem = untrusted_writers(conf_d, user); !problem.empty())
      refused.push_back(refusal(conf_d.string(), "a conf.d directory (it decides which fragments are merged)", problem));
  const std::vector<fs::path> fragment_files = config_fragment_files(source);
  std::vector<ConfigFragmentText> fragments;
  for (const auto& fragment : fragment_files) fragments.push_back({read_config_text(fragment, user, refused), fragment.string()});
  if (!refused.empty()) throw ConfigError(std::move(refused));
  LoadedConfig loaded = parse_robot_config(text, file.string(), source.parent_path(), options, fragments);
  loaded.config.source_file = source;
  loaded.config.fragment_files = fragment_files;
  return loaded;
}

}  // namespace rcand::config
