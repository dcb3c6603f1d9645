#include "libs/config/config_schema.hpp"
#include "libs/rcan/loopback.hpp"
#include "libs/rcan/web_origin.hpp"

#include "libs/yaml/yaml_document.hpp"

#include "libs/config/config_reference.hpp"
#include "libs/config/foreign_keys.hpp"

#include <rcand/sdk/scope.hpp>

#include <arpa/inet.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <stdexcept>
#include <unordered_map>

namespace rcand::config::detail {

using nlohmann::json;
using enum ValueType;
using yaml::child_path;
using yaml::item_path;
using yaml::resolve_plain_scalar;

namespace {

std::string check_sha256(const json& value) {
  const auto& text = value.get_ref<const std::string&>();
  const std::string expected =
      "expected the SHA-256 of the token as 64 lowercase hex characters (plain tokens are never stored; compute it "
      "with `printf %s TOKEN | sha256sum`)";
  if (text.size() != 64) return expected + ", found a string of " + std::to_string(text.size()) + " characters";
  for (const char c : text) {
    if (c >= 'A' && c <= 'F') return expected + ", found upper-case hex digits; write them in lower case";
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return expected + ", found a character that is not a hex digit";
  }
  return "";
}

// Any RCAN version is read (one of another major version with a warning, see robot_config.cpp); only something that
// is no version at all is refused.
std::string check_rcan_version(const json& value) {
  if (rcan_major_version(value.get_ref<const std::string&>())) return "";
  return "expected an RCAN version such as \"1.3\", found " + value.dump();
}

// runtime.listen.allowed_origins[]: an origin as a browser sends it; never "null" nor a wildcard.
std::string check_web_origin(const json& value) {
  const auto& text = value.get_ref<const std::string&>();
  if (text == "null") return "the opaque origin null (sandboxed frames, file:// pages: any page can be one) cannot be allowed";
  if (text.find('*') != std::string::npos) return "a wildcard would let any page drive the robot; list each origin";
  if (parse_web_origin(text)) return "";
  return "expected an origin such as \"https://fleet.example.com\" or \"http://192.168.1.20:8080\" (http or https, a host, "
         "an optional port, no path), found " +
         value.dump();
}

constexpr double kIntMax = INT_MAX;

// Every known key, in file order. Free-form blocks are `open` mappings with no children listed. A table, one key per
// row, kept in its hand layout (clang-format would give each field a line) and exempt from the function-size limit.
// clang-format off
const std::vector<KeySpec>& build_schema() {  // NOLINT(readability-function-size)
  static const std::vector<KeySpec> table = {
      {.path = "rcan_version", .type = String, .required = true, .non_empty = true, .check = check_rcan_version,
       .description = "RCAN version the file is written for, quoted (\"1.3\"); another major version is read as "
                      "1.3 with a warning"},

      {.path = "metadata", .type = Mapping, .required = true, .description = "who the robot is"},
      {.path = "metadata.robot_name", .type = String, .required = true, .non_empty = true,
       .description = "robot name, unique in a fleet (mDNS instance name, R2R id)"},
      {.path = "metadata.robot_uuid", .type = String, .non_empty = true,
       .description = "device id; its first 8 hex digits name the robot in its RURI (left out, or the all-zero "
                      "placeholder: derived from /etc/machine-id)"},
      {.path = "metadata.manufacturer", .type = String, .non_empty = true,
       .description = "manufacturer segment of the RURI (left out: \"unknown\", with a warning)"},
      {.path = "metadata.model", .type = String, .non_empty = true,
       .description = "model segment of the RURI (left out: robot_name as a slug, with a warning)"},
      {.path = "metadata.ruri", .type = String, .non_empty = true,
       .description = "the robot's RURI, when not derived from manufacturer, model and robot_uuid"},
      {.path = "metadata.description", .type = String, .description = "free text"},

      {.path = "agent", .type = Mapping, .description = "the AI brain; its presence declares `chat` (§9.3)"},
      {.path = "agent.provider", .type = String, .description = "brain provider"},
      {.path = "agent.model", .type = String, .description = "brain model"},
      {.path = "agent.fallbacks", .type = Sequence, .description = "brains tried in order when the provider fails"},
      {.path = "agent.confidence_gates", .type = Sequence, .description = "block/escalate/allow below a confidence"},
      {.path = "agent.hitl_gates", .type = Sequence, .description = "actions that wait for a human's approval"},
      {.path = "agent.latency_budget_ms", .type = Integer, .min = 0, .max = kIntMax,
       .description = "loss of the controlling link stops motion within this time"},
      {.path = "agent.min_obstacle_m", .type = Number, .min = 0,
       .description = "nearest obstacle distance that triggers the e-stop"},

      {.path = "physics", .type = Mapping, .description = "body and dead-reckoning calibration (§10.2)"},
      {.path = "physics.type", .type = String, .description = "body type, e.g. wheeled"},
      {.path = "physics.dof", .type = Integer, .min = 0, .max = kIntMax, .description = "degrees of freedom"},
      {.path = "physics.wheel_circumference_m", .type = Number, .min = 0, .min_exclusive = true,
       .description = "metres per full wheel rotation (needed for nav)"},
      {.path = "physics.turn_time_per_deg_s", .type = Number, .min = 0, .min_exclusive = true,
       .description = "seconds to turn one degree at speed 1.0 (needed for nav)"},
      {.path = "physics.max_wheel_rps", .type = Number, .default_value = 1.0, .min = 0, .min_exclusive = true,
       .description = "wheel rotations per second at speed 1.0"},
      {.path = "physics.wheel_base_m", .type = Number, .min = 0, .min_exclusive = true,
       .description = "distance between the wheels"},
      {.path = "physics.kinematics", .type = Sequence, .description = "arm links; with a dynamixel driver declares `arm`"},

      {.path = "drivers", .type = Sequence, .description = "hardware drivers, each served by a driver plugin"},
      {.path = "drivers[]", .type = Mapping, .open = true,
       .description = "one driver; keys beyond id and protocol are the plugin's settings"},
      {.path = "drivers[].id", .type = String, .non_empty = true, .unique = true,
       .description = "driver id, unique in the file (left out: <protocol><index>, with a warning)"},
      {.path = "drivers[].protocol", .type = String, .required = true, .non_empty = true,
       .description = "driver protocol a plugin provides (pca9685, dynamixel, sim, ...)"},
      {.path = "drivers[].port", .type = Any, .description = "device port (plugin-defined)"},
      {.path = "drivers[].address", .type = Any, .description = "bus address (plugin-defined)"},
      {.path = "drivers[].baud_rate", .type = Integer, .min = 0, .max = kIntMax, .min_exclusive = true,
       .description = "serial speed"},
      {.path = "drivers[].channels", .type = Mapping, .open = true, .description = "channel map (plugin-defined)"},

      // The camera's keys are known here (a misspelt one is an error at its line); their types and values are vision's
      // manifest schema's to check, reported with every other problem of the config (docs/protocol.md §10.6).
      {.path = "camera", .type = Mapping,
       .description = "the robot's camera (plugin org.rcand.vision); presence declares `vision`"},
      {.path = "camera.type", .type = Any,
       .description = "synthetic (test), file (video), v4l2 (usb, csi, webcam, uvc) or url (http, rtsp, ip, mjpeg); "
                      "left out: url if set, else path, else a V4L2 device"},
      {.path = "camera.device", .type = Any, .description = "V4L2 device path (/dev/video0, the default) or its number"},
      {.path = "camera.url", .type = Any,
       .description = "an http:// (MJPEG) or rtsp:// stream; credentials in it are never logged"},
      {.path = "camera.path", .type = Any, .description = "a video file, played in a loop"},
      {.path = "camera.file", .type = Any, .description = "the same as camera.path"},
      {.path = "camera.resolution", .type = Any, .description = "[width, height] in pixels (default [640, 480])"},
      {.path = "camera.width", .type = Any, .description = "width in pixels, instead of resolution"},
      {.path = "camera.height", .type = Any, .description = "height in pixels, instead of resolution"},
      {.path = "camera.fps", .type = Any, .description = "frames per second (default 30; a file: its own rate)"},
      {.path = "camera.framerate", .type = Any, .description = "the same as camera.fps"},
      {.path = "camera.fourcc", .type = Any, .description = "V4L2 pixel format asked for, e.g. MJPG or YUYV"},
      {.path = "camera.depth", .type = Any,
       .description = "synthetic (the synthetic depth scene: obstacle zones for nav and teleop) or false (default)"},
      {.path = "network", .type = Mapping, .open = true, .description = "network settings"},

      {.path = "rcan_protocol", .type = Mapping, .description = "how the robot speaks RCAN"},
      {.path = "rcan_protocol.port", .type = Integer, .default_value = 8000, .min = 0, .max = 65535,
       .description = "RCAN port"},
      {.path = "rcan_protocol.capabilities", .type = Sequence,
       .description = "declared capabilities; omit to auto-detect (§9.3), [] declares none"},
      {.path = "rcan_protocol.capabilities[]", .type = String, .non_empty = true,
       .description = "a §9 capability name or a reverse-domain custom one"},
      {.path = "rcan_protocol.enable_mdns", .type = Boolean, .default_value = false,
       .description = "advertise _rcan._tcp over mDNS"},
      {.path = "rcan_protocol.enable_jwt", .type = Boolean, .default_value = true, .description = "accept JWTs"},

      {.path = "safety", .type = Mapping, .description = "local safety bounds (§6)"},
      {.path = "safety.estop_on_startup", .type = Boolean, .default_value = false,
       .description = "start with the e-stop latched"},
      {.path = "safety.watchdog_ms", .type = Integer, .default_value = 500, .min = 0, .max = kIntMax,
       .min_exclusive = true, .description = "dead-man timeout of teleop motion"},
      {.path = "safety.obstacle_stop_cm", .type = Number, .min = 0,
       .description = "alias of agent.min_obstacle_m, in centimetres"},
      {.path = "safety.max_linear_speed", .type = Number, .default_value = 1.0, .min = 0, .max = 1,
       .description = "cap on normalised linear speed"},

      {.path = "runtime", .type = Mapping, .description = "rcand's own settings"},
      {.path = "runtime.listen", .type = Mapping, .description = "where the HTTP server listens"},
      {.path = "runtime.listen.address", .type = String, .default_value = "127.0.0.1", .non_empty = true,
       .description = "listen address"},
      {.path = "runtime.listen.port", .type = Integer, .min = 0, .max = 65535,
       .description = "listen port; rcan_protocol.port when absent"},
      {.path = "runtime.listen.tls", .type = Mapping,
       .description = "HTTPS and wss only on the listen address (TLS 1.2 or later); plain HTTP moves to 127.0.0.1"},
      {.path = "runtime.listen.tls.cert_file", .type = String, .required = true, .non_empty = true,
       .description = "PEM certificate chain, leaf first (relative to this file); read at start and on SIGHUP"},
      {.path = "runtime.listen.tls.key_file", .type = String, .required = true, .non_empty = true,
       .description = "its PEM private key, unencrypted, no access for other users (mode 600 or 640; relative to this file)"},
      {.path = "runtime.listen.tls.client_ca_file", .type = String, .non_empty = true,
       .description = "mutual TLS: clients must present a certificate signed by a CA in this PEM file (relative to this file)"},
      {.path = "runtime.listen.plain_loopback_port", .type = Integer, .min = 0, .max = 65535,
       .description = "with runtime.listen.tls: plain HTTP for local tools on 127.0.0.1 at this port; default the listen "
                      "port + 1 (0: any free port)"},
      {.path = "runtime.listen.allowed_origins", .type = Sequence,
       .description = "browser pages of other origins that may use the robot (docs/protocol.md §3.9); its own pages "
                      "always may. A name the robot is reached by (http://rover-3.lan:8000) belongs here too"},
      {.path = "runtime.listen.allowed_origins[]", .type = String, .non_empty = true, .check = check_web_origin,
       .description = "an origin: http(s)://host[:port], no path; never null or a wildcard"},
      {.path = "runtime.plugin_paths", .type = Sequence,
       .description = "folders searched for plugins (relative to this file)"},
      {.path = "runtime.plugin_paths[]", .type = String, .non_empty = true, .description = "a plugin folder"},
      {.path = "runtime.plugins", .type = Mapping, .description = "plugin development settings"},
      {.path = "runtime.plugins.allow_reload", .type = Boolean, .default_value = false,
       .description = "POST /api/plugins/<id>/reload (rcanctl plugins reload) may re-open a plugin from disk in the "
                      "running rcand, the e-stop latched first; for development robots only"},
      {.path = "runtime.auth", .type = Mapping, .description = "who may talk to the robot"},
      {.path = "runtime.auth.mode", .type = String, .default_value = "tokens", .choices = {"tokens", "open"},
       .description = "tokens: deny by default; open: no auth, loopback only"},
      {.path = "runtime.auth.jwt_secret_file", .type = String, .non_empty = true,
       .description = "file holding the HS256 secret (relative to this file)"},
      {.path = "runtime.auth.tokens", .type = Sequence, .description = "pre-shared tokens, stored as hashes"},
      {.path = "runtime.auth.tokens[]", .type = Mapping, .description = "one pre-shared token"},
      {.path = "runtime.auth.tokens[].principal", .type = String, .required = true, .non_empty = true,
       .description = "who holds the token (audit name)"},
      {.path = "runtime.auth.tokens[].role", .type = String, .required = true, .check = check_role,
       .description = "the token's role: GUEST, USER, LEASEE, OWNER or CREATOR (any case)"},
      {.path = "runtime.auth.tokens[].sha256", .type = String, .required = true, .unique = true, .secret = true,
       .check = check_sha256, .description = "SHA-256 of the token, 64 lowercase hex characters"},
      {.path = "runtime.logging", .type = Mapping, .description = "logging"},
      {.path = "runtime.logging.level", .type = String, .default_value = "info",
       .choices = {"trace", "debug", "info", "warn", "error"}, .description = "lowest level logged"},
      {.path = "runtime.swarm_file", .type = String, .default_value = "/etc/rcand/swarm.yaml", .non_empty = true,
       .description = "swarm peers file (relative to this file)"},
      {.path = "runtime.stop_path_priority", .type = Integer, .default_value = 10, .min = 0, .max = 99,
       .description = "SCHED_FIFO priority of the threads a stop runs on (the HTTP accept thread, the halt crew), so "
                       "a stop never waits for the scheduler; 0 = normal scheduling. Needs LimitRTPRIO= or CAP_SYS_NICE"},
      {.path = "runtime.max_connections", .type = Integer, .default_value = 10000, .min = 1, .max = 1000000,
       .description = "open HTTP connections served; beyond it (or the per-address cap) a new connection gets only "
                      "the e-stop answered, 503 SERVER_BUSY for anything else"},
      {.path = "runtime.max_connections_per_address", .type = Integer, .default_value = 256, .min = 1, .max = 1000000,
       .description = "open HTTP connections one client address may hold (so one host cannot fill max_connections)"},
      {.path = "runtime.max_streams_per_principal", .type = Integer, .default_value = 4, .min = 1, .max = 1000000,
       .description = "streamed answers (MJPEG viewers) one principal below OWNER may hold at once; beyond it 429 "
                      "TOO_MANY_STREAMS"},
      {.path = "runtime.max_streams_per_address", .type = Integer, .default_value = 8, .min = 1, .max = 1000000,
       .description = "streamed answers the principals below OWNER may hold at once from one client address (everyone "
                      "in auth mode open); beyond it 429 TOO_MANY_STREAMS"},
      {.path = "runtime.handler_timeout_ms", .type = Integer, .default_value = 10000, .min = 0, .max = kIntMax,
       .min_exclusive = true, .description = "longest a capability handler may run"},
      {.path = "runtime.plugin_start_timeout_ms", .type = Integer, .default_value = 10000, .min = 0, .max = kIntMax,
       .min_exclusive = true, .description = "longest a plugin's register(), factory, start() or routes() may take at startup"},
      {.path = "runtime.audit_file", .type = String, .non_empty = true,
       .description = "append every audit entry to this file as JSON lines (relative to this file)"},
      {.path = "runtime.audit_max_bytes", .type = Integer, .default_value = 67108864, .min = 4096, .max = 1e12,
       .description = "runtime.audit_file is rotated (FILE.1, FILE.2, ...) when a line would take it past this size"},
      {.path = "runtime.audit_keep_files", .type = Integer, .default_value = 4, .min = 1, .max = 100,
       .description = "rotated audit files kept (FILE.1 is the newest); older ones are deleted"},
      {.path = "runtime.state_dir", .type = String, .non_empty = true,
       .description = "where rcand keeps its e-stop latch and running marker across restarts (relative to this "
                      "file); default $STATE_DIRECTORY (systemd StateDirectory=), else /var/lib/rcand"},
      {.path = "runtime.rate_limit", .type = Mapping,
       .description = "request rate limits (429 with Retry-After); the e-stop paths are never limited"},
      {.path = "runtime.rate_limit.per_principal_per_s", .type = Number, .default_value = 100, .min = 0,
       .description = "requests per second each authenticated principal may make; 0 = unlimited"},
      {.path = "runtime.rate_limit.per_address_per_s", .type = Number, .default_value = 400, .min = 0,
       .description = "requests per second each client address may make, authenticated or not; 0 = unlimited"},
      {.path = "runtime.rate_limit.burst_s", .type = Number, .default_value = 2, .min = 0, .min_exclusive = true,
       .description = "a burst may use this many seconds' worth of requests at once"},
      {.path = "runtime.capabilities", .type = Mapping, .description = "per-capability plugin settings"},
      {.path = "runtime.capabilities.*", .type = Mapping, .open = true,
       .description = "settings of one capability (validated by its plugin)"},
      // Its keys are the R2R service's own (services/r2r/r2r_settings.cpp), joined through a ConfigFragment.
      {.path = "runtime.r2r", .type = Mapping, .open = true, .description = "robot-to-robot settings"},
  };
  return table;
}
// clang-format on

std::string_view parent_of(std::string_view schema_path) {
  if (schema_path.ends_with("[]")) return schema_path.substr(0, schema_path.size() - 2);
  const auto dot = schema_path.rfind('.');
  return dot == std::string_view::npos ? std::string_view{} : schema_path.substr(0, dot);
}

std::string_view last_segment(std::string_view schema_path) {
  const auto dot = schema_path.rfind('.');
  return dot == std::string_view::npos ? schema_path : schema_path.substr(dot + 1);
}

// The services' fragments, registered before main (ConfigFragment), and whether the index below was built already.
struct FragmentRegistry {
  std::vector<const std::vector<KeySpec>*> fragments;
  std::vector<std::pair<std::string_view, FragmentFileCheck>> file_checks;  // {block path, check}
  bool indexed = false;
};
FragmentRegistry& registry() {
  static FragmentRegistry instance;
  return instance;
}

struct SchemaIndex {
  std::vector<const KeySpec*> rows;  // the table's, then each fragment's
  std::unordered_map<std::string_view, const KeySpec*> by_path;
  std::unordered_map<std::string_view, std::vector<const KeySpec*>> children;  // named children of a mapping spec
};

const SchemaIndex& schema_index() {
  static const SchemaIndex index = [] {
    SchemaIndex built;
    for (const auto& spec : build_schema()) built.rows.push_back(&spec);
    registry().indexed = true;
    for (const auto* fragment : registry().fragments)
      for (const auto& spec : *fragment) built.rows.push_back(&spec);
    for (const KeySpec* spec : built.rows) {
      built.by_path.emplace(spec->path, spec);
      const auto name = last_segment(spec->path);
      if (!spec->path.ends_with("[]") && name != "*") built.children[parent_of(spec->path)].push_back(spec);
    }
    return built;
  }();
  return index;
}

const KeySpec kRootSpec{.path = "", .type = Mapping, .description = "the whole file"};

bool iequals(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
         });
}

std::string dump(const json& value) { return value.dump(-1, ' ', false, json::error_handler_t::replace); }

std::string type_phrase(ValueType type) {
  switch (type) {
    case Any: return "a value";
    case String: return "a string";
    case Integer: return "an integer";
    case Number: return "a number";
    case Boolean: return "a boolean (true or false)";
    case Mapping: return "a mapping";
    case Sequence: return "a sequence";
  }
  return "a value";
}

std::string number_text(double value) {
  if (std::isnan(value)) return ".nan";
  if (std::isinf(value)) return value < 0 ? "-.inf" : ".inf";
  // Bounds like 65535 read better without json's ".0".
  if (value == std::floor(value) && std::abs(value) < 1e15) return std::to_string(static_cast<long long>(value));
  return dump(json(value));
}

std::string describe(const json& value, bool secret) {
  switch (value.type()) {
    case json::value_t::null: return "null (no value)";
    case json::value_t::boolean: return std::string("the boolean ") + (value.get<bool>() ? "true" : "false");
    case json::value_t::number_integer:
    case json::value_t::number_unsigned: return "the integer " + dump(value);
    case json::value_t::number_float: return "the number " + number_text(value.get<double>());
    case json::value_t::string: {
      const auto& text = value.get_ref<const std::string&>();
      if (secret) return "a string of " + std::to_string(text.size()) + " characters";
      constexpr std::size_t kShown = 40;
      if (text.size() <= kShown) return "the string " + dump(value);
      return "the string " + dump(json(text.substr(0, kShown))) + "...";
    }
    case json::value_t::object: return "a mapping";
    case json::value_t::array: return "a sequence";
    default: return "a value";
  }
}

}  // namespace

// Role names come from the SDK, the same parser auth uses, so the file and the runtime cannot disagree.
std::string check_role(const json& value) {
  const auto& text = value.get_ref<const std::string&>();
  if (sdk::parse_role(text)) return "";
  std::vector<std::string> names;
  std::string list;
  for (const auto role : {sdk::Role::Guest, sdk::Role::User, sdk::Role::Leasee, sdk::Role::Owner, sdk::Role::Creator}) {
    names.emplace_back(sdk::role_name(role));
    list += (list.empty() ? "" : ", ") + names.back();
  }
  std::string message = "must be one of " + list + " (any case), found " + describe(value, false);
  if (const auto guess = closest_match(text, names)) message += "; did you mean '" + *guess + "'?";
  return message;
}

namespace {

bool type_matches(ValueType type, const json& value) {
  switch (type) {
    case Any: return true;
    case String: return value.is_string();
    case Integer: return value.is_number_integer();
    case Number: return value.is_number() && std::isfinite(value.get<double>());
    case Boolean: return value.is_boolean();
    case Mapping: return value.is_object();
    case Sequence: return value.is_array();
  }
  return false;
}

// What the operator most likely meant, appended to a type error.
std::string type_hint(ValueType expected, const json& value) {
  if (value.is_string()) {
    const auto& text = value.get_ref<const std::string&>();
    const json plain = resolve_plain_scalar(text);
    if ((expected == Integer || expected == Number) && plain.is_number()) return "; remove the quotes to make it a number";
    if (expected == Boolean && plain.is_boolean()) return "; remove the quotes to make it a boolean";
    if (expected == Boolean) return "; write true or false";
    if (expected == Sequence) return "; write [a, b] or one '- item' per line";
  }
  if (expected == String && (value.is_number() || value.is_boolean()))
    return "; put it in quotes so it stays text exactly as written";
  if (expected == Integer && value.is_number_float()) return "; write a whole number without a decimal point";
  if (expected == Number && value.is_number_float()) return "; expected a finite number";
  if (expected == Sequence && value.is_null()) return "; write [] for an empty list";
  return "";
}

class Validator {
 public:
  Validator(const std::map<std::string, SourceMark>& marks, const std::string& file, std::vector<ConfigDiagnostic>& out)
      : marks_(marks), file_(file), out_(out) {}

  void check(const KeySpec& spec, const json& value, const std::string& key_path) {
    if (value.is_null() && spec.type != Sequence) {
      // `block:` with nothing under it is an empty block; an optional scalar with no value is as if absent.
      if (spec.type == Mapping) check_mapping(spec, json::object(), key_path);
      else if (spec.required || spec.path.ends_with("[]"))  // a list item has no "absent" to fall back on
        error(key_path, "expected " + type_phrase(spec.type) + ", found null (no value)");
      return;
    }
    if (!type_matches(spec.type, value)) {
      error(key_path,
            "expected " + type_phrase(spec.type) + ", found " + describe(value, spec.secret) + type_hint(spec.type, value));
      return;
    }
    check_constraints(spec, value, key_path);
    if (spec.type == Mapping) check_mapping(spec, value, key_path);
    if (spec.type == Sequence) {
      const KeySpec* item = find_spec(std::string(spec.path) + "[]");
      if (item == nullptr) return;  // free-form items
      for (std::size_t i = 0; i < value.size(); ++i) check(*item, value[i], item_path(key_path, i));
    }
  }

  void error(const std::string& key_path, std::string message) {
    out_.push_back({ConfigDiagnostic::Severity::Error, mark(key_path), key_path, std::move(message)});
  }
  void warning(const std::string& key_path, std::string message) {
    out_.push_back({ConfigDiagnostic::Severity::Warning, mark(key_path), key_path, std::move(message)});
  }
  SourceMark mark(const std::string& key_path) const { return nearest_mark(marks_, file_, key_path); }

 private:
  void check_constraints(const KeySpec& spec, const json& value, const std::string& key_path) {
    if (value.is_string()) {
      const auto& text = value.get_ref<const std::string&>();
      if (spec.non_empty && text.empty()) return error(key_path, "must not be empty");
      if (!spec.choices.empty()) check_choice(spec, text, key_path);
    }
    if (value.is_number() && (spec.min || spec.max)) {
      const double number = value.get<double>();
      const bool below = spec.min && (spec.min_exclusive ? number <= *spec.min : number < *spec.min);
      const bool above = spec.max && number > *spec.max;
      if (below || above) {
        std::string bound;
        if (spec.min && spec.max && !spec.min_exclusive)
          bound = "between " + number_text(*spec.min) + " and " + number_text(*spec.max);
        else if (spec.min && spec.max)
          bound = "greater than " + number_text(*spec.min) + " and at most " + number_text(*spec.max);
        else if (spec.min) bound = (spec.min_exclusive ? "greater than " : "at least ") + number_text(*spec.min);
        else bound = "at most " + number_text(*spec.max);
        return error(key_path, "must be " + bound + ", found " + describe(value, spec.secret));
      }
    }
    if (spec.check != nullptr) {
      if (std::string problem = spec.check(value); !problem.empty()) return error(key_path, std::move(problem));
    }
    if (spec.unique) check_unique(spec, value, key_path);
  }

  void check_choice(const KeySpec& spec, const std::string& text, const std::string& key_path) {
    for (const auto choice : spec.choices)
      if (spec.ignore_case ? iequals(choice, text) : choice == text) return;
    std::vector<std::string> names(spec.choices.begin(), spec.choices.end());
    std::string list;
    for (const auto& name : names) list += (list.empty() ? "" : ", ") + name;
    std::string message =
        "must be one of " + list + (spec.ignore_case ? " (any case)" : "") + ", found " + describe(json(text), spec.secret);
    if (!spec.secret)
      if (const auto guess = closest_match(text, names)) message += "; did you mean '" + *guess + "'?";
    error(key_path, std::move(message));
  }

  void check_unique(const KeySpec& spec, const json& value, const std::string& key_path) {
    auto& seen = seen_[spec.path];
    const auto [it, inserted] = seen.emplace(dump(value), key_path);
    if (inserted) return;
    const std::string first = it->second + " (line " + std::to_string(mark(it->second).line) + ")";
    if (spec.secret) return error(key_path, "the same value is already used by " + first);
    error(key_path, "duplicate value " + dump(value) + "; already used by " + first);
  }

  void check_mapping(const KeySpec& spec, const json& value, const std::string& key_path) {
    const std::string schema_path(spec.path);
    for (const auto& [name, child] : value.items()) {
      const std::string child_key = child_path(key_path, name);
      if (const KeySpec* known = find_spec(child_path(schema_path, name))) check(*known, child, child_key);
      else if (const KeySpec* any = find_spec(child_path(schema_path, "*"))) check(*any, child, child_key);
      else if (!spec.open) unknown_key(schema_path, key_path, name, child_key);
    }
    const auto children = schema_index().children.find(spec.path);
    if (children == schema_index().children.end()) return;
    for (const KeySpec* child : children->second) {
      const std::string name(last_segment(child->path));
      const auto condition = child->required_if.empty() ? value.end() : value.find(std::string(child->required_if));
      const bool required_now = condition != value.end() && *condition == true;
      if (!(child->required || required_now) || value.contains(name)) continue;
      if (!child->required_unless.empty() && value.contains(std::string(child->required_unless))) continue;
      std::string message = "required key '" + name + "' is missing";
      if (!child->required_unless.empty()) message += " (give '" + name + "' or '" + std::string(child->required_unless) + "')";
      if (required_now) message += " (" + std::string(child->required_if) + " is true, so " + name + " must be set)";
      message += "; expected " + type_phrase(child->type) + ": " + std::string(child->description);
      // The key is not in the file, so point at the block that should hold it.
      out_.push_back({ConfigDiagnostic::Severity::Error, mark(key_path), child_path(key_path, name), std::move(message)});
    }
  }

 public:
  // The one warning that lists every ignored key (other runtimes' and newer RCAN versions'), at the first of them.
  void finish() {
    if (ignored_.empty()) return;
    std::stable_sort(ignored_.begin(), ignored_.end(), [](const IgnoredKey& a, const IgnoredKey& b) {
      return std::pair(a.mark.line, a.mark.column) < std::pair(b.mark.line, b.mark.column);
    });  // file order (a mapping's keys are walked by name)
    std::string list;
    for (const auto& key : ignored_) list += (list.empty() ? "" : ", ") + key.text;
    const std::size_t count = ignored_.size();
    warning_at(ignored_.front().mark, "",
               std::to_string(count) + (count == 1 ? " key" : " keys") +
                   " of other RCAN versions or runtimes, not implemented by rcand (RCAN 1.3), ignored: " + list);
    ignored_.clear();
  }

 private:
  struct IgnoredKey {
    SourceMark mark;
    std::string text;  // "port (line 9; newer RCAN, rcand reads rcan_protocol.port)"
  };

  void warning_at(SourceMark where, const std::string& key_path, std::string message) {
    out_.push_back({ConfigDiagnostic::Severity::Warning, std::move(where), key_path, std::move(message)});
  }

  void unknown_key(const std::string& schema_path, const std::string& key_path, const std::string& name,
                   const std::string& child_key) {
    std::vector<std::string> allowed;
    if (const auto it = schema_index().children.find(schema_path); it != schema_index().children.end())
      for (const KeySpec* child : it->second) allowed.emplace_back(last_segment(child->path));
    const ForeignKey* foreign = find_foreign_key(child_path(schema_path, name));
    // A near miss of a key this block takes is a typo whose setting would be silently lost ("rcan_protocl:" and the
    // robot advertises what it auto-detects): an error. A key another runtime or RCAN version is known to use never
    // is, however close it looks; it and every other unknown key join the one warning of ignored keys.
    if (const auto guess = foreign ? std::nullopt : closest_match(name, allowed))
      return out_.push_back({ConfigDiagnostic::Severity::Error, mark(child_key), key_path,
                             "unknown key '" + name + "'; did you mean '" + *guess + "'?"});
    const SourceMark where = mark(child_key);
    std::string text = child_key + " (line " + std::to_string(where.line);
    if (foreign != nullptr) {
      text += foreign->origin == ForeignKey::Origin::NewerRcan ? "; newer RCAN" : "; another runtime's";
      if (!foreign->rcand_reads.empty()) text += ", rcand reads " + std::string(foreign->rcand_reads);
    } else if (const auto elsewhere = known_elsewhere(name)) {
      text += "; rcand reads " + *elsewhere;
    }
    ignored_.push_back({where, text + ")"});
  }

  // A key written in the wrong block ("plugin_paths" at the top instead of under runtime).
  static std::optional<std::string> known_elsewhere(const std::string& name) {
    for (const KeySpec* spec : config_schema()) {
      if (spec->path.find('[') != std::string_view::npos || spec->path.find('*') != std::string_view::npos) continue;
      if (spec->path.find('.') != std::string_view::npos && iequals(last_segment(spec->path), name))
        return std::string(spec->path);
    }
    return std::nullopt;
  }

  const std::map<std::string, SourceMark>& marks_;
  const std::string& file_;
  std::vector<ConfigDiagnostic>& out_;
  std::map<std::string_view, std::map<std::string, std::string>> seen_;  // unique spec -> value -> first key path
  std::vector<IgnoredKey> ignored_;
};

const json* at(const json& doc, std::initializer_list<const char*> keys) {
  const json* node = &doc;
  for (const char* key : keys) {
    if (!node->is_object()) return nullptr;
    const auto it = node->find(key);
    if (it == node->end()) return nullptr;
    node = &*it;
  }
  return node;
}

// Rules that span several keys, checked after the table walk on values that already have the right type.
void check_cross_field_rules(const json& doc, Validator& validator) {
  const json* mode = at(doc, {"runtime", "auth", "mode"});
  const json* address = at(doc, {"runtime", "listen", "address"});
  if (mode && mode->is_string() && *mode == "open") {
    const std::string listen = address && address->is_string() ? address->get<std::string>() : "127.0.0.1";
    if (!is_loopback_address(std::string(listen)))
      validator.error("runtime.auth.mode",
                      "\"open\" mode (no authentication) is allowed only on a loopback address, but "
                      "runtime.listen.address is " +
                          dump(json(listen)) + "; use mode \"tokens\" or listen on 127.0.0.1");
  }

  const json* metres = at(doc, {"agent", "min_obstacle_m"});
  const json* centimetres = at(doc, {"safety", "obstacle_stop_cm"});
  if (metres && centimetres && metres->is_number() && centimetres->is_number()) {
    const double m = metres->get<double>(), cm = centimetres->get<double>();
    if (std::abs(m * 100.0 - cm) > 1e-6 * std::max(1.0, std::abs(cm)))
      validator.warning("safety.obstacle_stop_cm",
                        "disagrees with agent.min_obstacle_m (" + number_text(m) + " m); agent.min_obstacle_m is used");
  }
}

}  // namespace

std::optional<int> rcan_major_version(std::string_view text) noexcept {
  if (text.starts_with('v') || text.starts_with('V')) text.remove_prefix(1);
  int major = 0;
  std::size_t digits = 0;
  for (; digits < text.size() && digits < 4 && text[digits] >= '0' && text[digits] <= '9'; ++digits)
    major = major * 10 + (text[digits] - '0');
  if (digits == 0 || (digits < text.size() && text[digits] != '.' && text[digits] != '-')) return std::nullopt;
  return major;
}

const std::vector<const KeySpec*>& config_schema() { return schema_index().rows; }

const KeySpec* find_spec(std::string_view schema_path) {
  const auto& index = schema_index().by_path;
  const auto it = index.find(schema_path);
  return it == index.end() ? nullptr : it->second;
}

const json& schema_default(std::string_view schema_path) {
  static const json none = nullptr;
  const KeySpec* spec = find_spec(schema_path);
  return spec ? spec->default_value : none;
}

void check_fragment_files(const json& doc, const std::map<std::string, SourceMark>& marks, const std::string& file,
                          const std::filesystem::path& base_dir, std::vector<ConfigDiagnostic>& out) {
  for (const auto& [block_path, files] : registry().file_checks) {
    const json* block = &doc;
    for (std::size_t at = 0; block != nullptr && at <= block_path.size();) {
      const std::size_t dot = std::min(block_path.find('.', at), block_path.size());
      const auto it = block->is_object() ? block->find(std::string(block_path.substr(at, dot - at))) : block->end();
      block = block->is_object() && it != block->end() ? &*it : nullptr;
      at = dot + 1;
    }
    if (block == nullptr || block->is_null()) continue;
    for (auto& [key_path, problem] : files(*block, base_dir)) {
      ConfigDiagnostic diagnostic;
      diagnostic.mark = yaml::nearest_mark(marks, file, key_path);
      diagnostic.key_path = key_path;
      diagnostic.message = std::move(problem);
      out.push_back(std::move(diagnostic));
    }
  }
}

void validate_config(const json& doc, const std::map<std::string, SourceMark>& marks, const std::string& file,
                     std::vector<ConfigDiagnostic>& out) {
  Validator validator(marks, file, out);
  if (!doc.is_object()) {
    validator.error("",
                    "expected a mapping of blocks (rcan_version, metadata, ...) at the top level, found " + describe(doc, false));
    return;
  }
  validator.check(kRootSpec, doc, "");
  validator.finish();
  check_cross_field_rules(doc, validator);
}

}  // namespace rcand::config::detail

namespace rcand::config {

ConfigFragment::ConfigFragment(std::vector<KeySpec> rows) : rows_(std::move(rows)) {
  auto& registry = detail::registry();
  if (registry.indexed) throw std::logic_error("a config fragment was registered after the first validation");
  registry.fragments.push_back(&rows_);
}

ConfigFragment::ConfigFragment(std::vector<KeySpec> rows, std::string_view block_path, FragmentFileCheck files)
    : ConfigFragment(std::move(rows)) {
  detail::registry().file_checks.emplace_back(block_path, files);
}

void ConfigFragment::check(const nlohmann::json& block, std::string_view schema_path) const {
  const KeySpec* spec = detail::find_spec(schema_path);
  if (spec == nullptr) throw std::logic_error("no config key " + std::string(schema_path));
  const std::map<std::string, SourceMark> no_marks;
  const std::string no_file;
  std::vector<ConfigDiagnostic> found;
  detail::Validator validator(no_marks, no_file, found);
  validator.check(*spec, block, std::string(schema_path));
  for (const auto& diagnostic : found)
    if (diagnostic.severity == ConfigDiagnostic::Severity::Error)
      throw std::invalid_argument(diagnostic.key_path + ": " + diagnostic.message);
}

std::string config_reference() {
  using detail::config_schema;
  std::size_t width = 0;
  for (const KeySpec* row : config_schema()) width = std::max(width, row->path.size());
  std::string out;
  for (const KeySpec* row : config_schema()) {
    const KeySpec& spec = *row;
    std::string line(spec.path);
    line.resize(width + 2, ' ');
    std::string type = detail::type_phrase(spec.type);
    type = type.substr(type.find(' ') + 1);  // "a number" -> "number"
    type = type.substr(0, type.find(' '));   // "boolean (true or false)" -> "boolean"
    type.resize(std::max<std::size_t>(type.size(), 8) + 2, ' ');
    line += type;
    std::string status = spec.required                   ? "required"
                         : !spec.default_value.is_null() ? "default " + detail::dump(spec.default_value)
                                                         : "optional";
    status.resize(std::max<std::size_t>(status.size(), 32) + 2, ' ');
    line += status;
    line += spec.description;
    if (spec.min || spec.max) {
      line += " [";
      if (spec.min && spec.max && !spec.min_exclusive) line += detail::number_text(*spec.min) + "..";
      else if (spec.min) line += (spec.min_exclusive ? "> " : ">= ") + detail::number_text(*spec.min);
      if (spec.min && spec.max && spec.min_exclusive) line += ", ";
      if (spec.max) line += (spec.min && !spec.min_exclusive ? "" : "<= ") + detail::number_text(*spec.max);
      line += "]";
    }
    if (!spec.choices.empty()) {
      std::string list;
      for (const auto choice : spec.choices) list += (list.empty() ? "" : "|") + std::string(choice);
      line += " [" + list + "]";
    }
    out += line + "\n";
  }
  return out;
}

}  // namespace rcand::config
