#include "services/r2r/r2r_settings.hpp"

#include <algorithm>
#include <stdexcept>

#include "libs/base/file_exposure.hpp"
#include "libs/config/config_schema.hpp"
#include "libs/r2r_wire/peers_file.hpp"
#include "libs/rcan/secret_file.hpp"

namespace rcand::services::r2r {

namespace {

using nlohmann::json;
using enum config::ValueType;
using config::detail::check_role;

std::string check_one_key(const json& peer) {
  if (peer.contains("public_key_file") == peer.contains("public_key"))
    return "give exactly one of public_key_file and public_key";
  return "";
}

std::vector<std::pair<std::string, std::string>> check_r2r_files(const json& block, const std::filesystem::path& base_dir);

// runtime.r2r: this service's keys. They join the config's one table (libs/config/config_schema.hpp), so the file
// is checked with file:line:column before anything here runs; load_r2r_settings() runs the same check on a block it
// is handed directly. A table, one key per row, kept in its hand layout.
// clang-format off
const config::ConfigFragment kR2rKeys({
    // The protocol core (docs/protocol.md §11, README "R2R").
    {.path = "runtime.r2r.origin", .type = Mapping, .description = "where this robot's dead-reckoning frame starts in the fleet frame"},
    {.path = "runtime.r2r.origin.x", .type = Number, .default_value = 0, .description = "metres"},
    {.path = "runtime.r2r.origin.y", .type = Number, .default_value = 0, .description = "metres"},
    {.path = "runtime.r2r.origin.heading_deg", .type = Number, .default_value = 0, .description = "degrees, counter-clockwise"},
    {.path = "runtime.r2r.status_interval_ms", .type = Integer, .default_value = 1000, .min = 0, .max = 3600000,
     .min_exclusive = true, .description = "how often status is sent (and on change)"},
    // bid_window_ms, cost_per_queued_task_s and max_held_tasks are read by the fleet plugin (org.rcand.fleet,
    // plugins/fleet/fleet_settings.cpp), which runs the auctions; they stay here so one table checks runtime.r2r.
    {.path = "runtime.r2r.bid_window_ms", .type = Integer, .default_value = 1000, .min = 0, .max = 3600000,
     .min_exclusive = true, .description = "how long an auction this robot opens collects bids"},
    {.path = "runtime.r2r.cost_per_queued_task_s", .type = Number, .default_value = 30, .min = 0,
     .description = "seconds each task already held adds to a bid"},
    {.path = "runtime.r2r.require_signatures", .type = Boolean, .default_value = false,
     .description = "refuse R2R messages without a valid Ed25519 signature (code 103)"},
    {.path = "runtime.r2r.replay_window_s", .type = Number, .default_value = 30, .min = 0, .min_exclusive = true,
     .description = "signed messages older than this are refused (code 103)"},
    {.path = "runtime.r2r.max_peers", .type = Integer, .default_value = 1024, .min = 1, .max = 1000000,
     .description = "peers remembered in GET /api/r2r/peers; beyond it the least recently heard is forgotten"},
    {.path = "runtime.r2r.peer_expiry_s", .type = Number, .default_value = 120, .min = 0, .min_exclusive = true,
     .description = "a peer heard nothing from for this long is forgotten"},
    {.path = "runtime.r2r.max_held_tasks", .type = Integer, .default_value = 64, .min = 1, .max = 1000000,
     .description = "tasks this robot holds at once; beyond it requests and awards are declined"},
    {.path = "runtime.r2r.private_key_file", .type = String, .non_empty = true, .required_if = "require_signatures",
     .description = "this robot's Ed25519 private key, PEM (relative to this file); signs every R2R message"},
    {.path = "runtime.r2r.token_file", .type = String, .non_empty = true,
     .description = "file holding the token this robot sends in header.auth.token (relative to this file)"},
    {.path = "runtime.r2r.peers", .type = Sequence, .description = "peers whose signatures this robot accepts"},
    {.path = "runtime.r2r.peers[]", .type = Mapping, .check = check_one_key,
     .description = "one peer: name, public_key_file or public_key, role"},
    {.path = "runtime.r2r.peers[].name", .type = String, .required = true, .non_empty = true, .unique = true,
     .description = "the peer's robot name, also its signature key_id"},
    {.path = "runtime.r2r.peers[].public_key_file", .type = String, .non_empty = true,
     .description = "the peer's Ed25519 public key, PEM (relative to this file)"},
    {.path = "runtime.r2r.peers[].public_key", .type = String, .non_empty = true,
     .description = "the peer's Ed25519 public key: 32 bytes, base64"},
    {.path = "runtime.r2r.peers[].role", .type = String, .default_value = "USER", .check = check_role,
     .description = "what the peer's signed messages may do: GUEST, USER, LEASEE, OWNER or CREATOR"},
    {.path = "runtime.r2r.peers_file", .type = String, .non_empty = true,
     .description = "the fleet's peers file (YAML {peers: [{name, public_key|public_key_file, role}]}, relative to this "
                    "file; rcanctl fleet enroll writes it): merged with peers, re-read on SIGHUP"},
    // The transports (WebSocket /ws/r2r, UDP status, MQTT).
    {.path = "runtime.r2r.enabled", .type = Boolean, .default_value = false,
     .description = "speak R2R (seed 004): WS /ws/r2r, UDP status, MQTT when configured"},
    {.path = "runtime.r2r.ws_dial", .type = Boolean,
     .description = "dial swarm.yaml peers over WebSocket when a message must reach them (default: when no mqtt)"},
    {.path = "runtime.r2r.ws_max_connections", .type = Integer, .default_value = 256, .min = 1, .max = 1000000,
     .description = "inbound WS /ws/r2r connections; beyond it the upgrade answers 503 UNAVAILABLE"},
    {.path = "runtime.r2r.ws_max_connections_per_principal", .type = Integer, .default_value = 8, .min = 1, .max = 1000000,
     .description = "inbound /ws/r2r connections one principal below OWNER may hold; beyond it 429 TOO_MANY_CONNECTIONS"},
    {.path = "runtime.r2r.ws_max_connections_per_address", .type = Integer, .default_value = 16, .min = 1, .max = 1000000,
     .description = "inbound /ws/r2r connections the principals below OWNER may hold from one client address (everyone "
                    "in auth mode open); beyond it 429 TOO_MANY_CONNECTIONS"},
    {.path = "runtime.r2r.ws_reserved_connections", .type = Integer, .default_value = 32, .min = 0, .max = 1000000,
     .description = "of ws_max_connections, the last ones only OWNER and CREATOR get (503 R2R_SLOTS_RESERVED to others)"},
    {.path = "runtime.r2r.ws_max_queued_bytes", .type = Integer, .default_value = 1048576, .min = 1024, .max = 1073741824,
     .description = "bytes queued to one /ws/r2r connection; a client that does not read past it is closed"},
    {.path = "runtime.r2r.udp_enabled", .type = Boolean, .default_value = true,
     .description = "send and receive status over UDP"},
    {.path = "runtime.r2r.udp_port", .type = Integer, .min = 0, .max = 65535,
     .description = "UDP port for status; rcan_protocol.port when absent"},
    {.path = "runtime.r2r.udp_bind", .type = String, .non_empty = true,
     .description = "UDP bind address; 0.0.0.0 (the listen address when it is loopback)"},
    {.path = "runtime.r2r.udp_broadcast", .type = Sequence,
     .description = "where status datagrams go (e.g. [\"192.168.1.255\"]); none when absent: UDP status is not sent"},
    {.path = "runtime.r2r.udp_broadcast[]", .type = String, .non_empty = true,
     .description = "an IP address, optionally with :port"},
    {.path = "runtime.r2r.mqtt", .type = Mapping, .open = true, .description = "MQTT broker for R2R (topics r2r/<name>, r2r/broadcast, r2r/status/<name>)"},
    {.path = "runtime.r2r.mqtt.host", .type = String, .non_empty = true, .description = "broker host"},
    {.path = "runtime.r2r.mqtt.port", .type = Integer, .min = 1, .max = 65535,
     .description = "broker port (1883, or 8883 with tls)"},
    {.path = "runtime.r2r.mqtt.tls", .type = Mapping, .description = "TLS to the broker"},
    {.path = "runtime.r2r.mqtt.tls.ca_file", .type = String, .required = true, .non_empty = true,
     .description = "CA certificate the broker's certificate must chain to"},
    {.path = "runtime.r2r.mqtt.tls.cert_file", .type = String, .non_empty = true, .description = "client certificate"},
    {.path = "runtime.r2r.mqtt.tls.key_file", .type = String, .non_empty = true, .description = "client key"},
    {.path = "runtime.r2r.mqtt.username", .type = String, .non_empty = true,
     .description = "broker user name (default: the robot name when a password or token is set)"},
    {.path = "runtime.r2r.mqtt.password_file", .type = String, .non_empty = true,
     .description = "file holding the broker password"},
    {.path = "runtime.r2r.mqtt.token_file", .type = String, .non_empty = true,
     .description = "file holding a token sent as the broker password"},
    {.path = "runtime.r2r.mqtt.client_id", .type = String, .non_empty = true,
     .description = "MQTT client id (default rcand-<robot name>)"},
    {.path = "runtime.r2r.mqtt.keepalive_s", .type = Integer, .default_value = 30, .min = 5, .max = 65535,
     .description = "MQTT keep-alive"},
    {.path = "runtime.r2r.mqtt.status_subscriptions", .type = Any,
     .description = "whose status this robot reads (r2r/status/<name>): a list of robot names, or all; none by default"},
}, "runtime.r2r", check_r2r_files);
// clang-format on

constexpr std::string_view kBlock = "runtime.r2r";

[[noreturn]] void bad(const std::string& key, const std::string& message) {
  throw std::invalid_argument("runtime.r2r." + key + ": " + message);
}

// The value written at `key` (dotted, under runtime.r2r), else the table's default for it (null when it has none).
json read(const json& block, const std::string& key) {
  const json* node = &block;
  for (std::size_t at = 0; node != nullptr && at <= key.size();) {
    const std::size_t dot = std::min(key.find('.', at), key.size());
    const auto it = node->is_object() ? node->find(key.substr(at, dot - at)) : node->end();
    node = node->is_object() && it != node->end() ? &*it : nullptr;
    at = dot + 1;
  }
  if (node != nullptr && !node->is_null()) return *node;
  return config::detail::schema_default(std::string(kBlock) + "." + key);
}

std::filesystem::path resolve(const std::filesystem::path& base, const std::string& file) {
  const std::filesystem::path p(file);
  return p.is_absolute() ? p : base / p;
}

// A token file, read like every secret (libs/rcan/secret_file.hpp); trailing blanks are never part of a token.
std::string read_token_file(const std::filesystem::path& file, const std::string& key, std::vector<std::string>& warnings) {
  SecretFile read = read_secret_file(file);
  if (!read.secret) bad(key, read.error);
  if (!read.warning.empty()) warnings.push_back(std::string(kBlock) + "." + key + ": " + read.warning);
  std::string token = std::move(*read.secret);
  while (!token.empty() && (token.back() == ' ' || token.back() == '\t')) token.pop_back();
  if (token.empty()) bad(key, file.string() + " is empty");
  return token;
}

// The peers whose signatures this robot accepts; their keys are read from files or parsed here.
std::vector<r2r_wire::PeerKey> read_peers(const json& peers, const std::filesystem::path& base_dir) {
  std::vector<r2r_wire::PeerKey> out;
  for (std::size_t i = 0; peers.is_array() && i < peers.size(); ++i) {
    const json& entry = peers[i];
    r2r_wire::PeerKey peer;
    peer.name = entry["name"].get<std::string>();
    const json role = entry.contains("role") && !entry["role"].is_null()
                          ? entry["role"]
                          : config::detail::schema_default("runtime.r2r.peers[].role");
    peer.role = sdk::parse_role(role.get<std::string>()).value();  // checked by the table
    const bool has_file = entry.contains("public_key_file");
    const std::string key = has_file ? "public_key_file" : "public_key";
    try {
      peer.key = std::make_shared<const r2r_wire::Ed25519Key>(
          has_file ? r2r_wire::Ed25519Key::public_from_file(resolve(base_dir, entry[key].get<std::string>()))
                   : r2r_wire::Ed25519Key::public_from_text(entry[key].get<std::string>()));
    } catch (const std::exception& e) {
      bad("peers[" + std::to_string(i) + "]." + key, e.what());
    }
    out.push_back(std::move(peer));
  }
  return out;
}

// At start, --check-config and each SIGHUP reload (config_schema.hpp): the peers file exists, parses, every key
// decodes, and no robot is both in it and inline. A public key is no secret: its file mode is not checked.
std::vector<std::pair<std::string, std::string>> check_r2r_files(const json& block, const std::filesystem::path& base_dir) {
  const auto file = block.find("peers_file");
  if (file == block.end() || !file->is_string()) return {};
  try {
    const r2r_wire::LoadedPeers loaded = r2r_wire::load_peers_file(resolve(base_dir, file->get<std::string>()));
    const json peers = block.contains("peers") ? block["peers"] : json::array();
    for (std::size_t i = 0; peers.is_array() && i < peers.size(); ++i)
      for (std::size_t j = 0; j < loaded.peers.size(); ++j)
        if (peers[i].is_object() && peers[i].value("name", "") == loaded.peers[j].name)
          return {{"runtime.r2r.peers[" + std::to_string(i) + "].name",
                   "'" + loaded.peers[j].name + "' is also in the peers file at " + loaded.where[j] + ": keep one"}};
  } catch (const std::exception& e) {
    return {{"runtime.r2r.peers_file", e.what()}};
  }
  return {};
}

}  // namespace

std::vector<r2r_wire::PeerKey> reload_peers(const R2rSettings& settings) {
  if (!settings.peers_file) return settings.inline_peers;
  return r2r_wire::merge_peers(settings.inline_peers, settings.inline_where, r2r_wire::load_peers_file(*settings.peers_file));
}

R2rSettings load_r2r_settings(const json& r2r, const std::filesystem::path& base_dir) {
  R2rSettings s;
  if (r2r.is_null()) return s;
  kR2rKeys.check(r2r, kBlock);  // from here on every value has its type and bounds
  s.origin = {read(r2r, "origin.x").get<double>(), read(r2r, "origin.y").get<double>(),
              read(r2r, "origin.heading_deg").get<double>()};
  s.status_interval = std::chrono::milliseconds(read(r2r, "status_interval_ms").get<std::int64_t>());
  s.auth.replay_window_s = read(r2r, "replay_window_s").get<double>();
  s.max_peers = read(r2r, "max_peers").get<std::size_t>();
  s.peer_expiry_s = read(r2r, "peer_expiry_s").get<double>();
  s.auth.require_signatures = read(r2r, "require_signatures").get<bool>();
  if (const json file = read(r2r, "token_file"); file.is_string())
    s.outbound_token = read_token_file(resolve(base_dir, file.get<std::string>()), "token_file", s.warnings);
  if (const json file = read(r2r, "private_key_file"); file.is_string()) {
    const auto path = resolve(base_dir, file.get<std::string>());
    try {
      s.private_key = std::make_shared<const r2r_wire::Ed25519Key>(r2r_wire::Ed25519Key::private_from_file(path));
    } catch (const std::exception& e) {
      bad("private_key_file", e.what());
    }
    if (auto problem = others_may_access(path, "this private key"); !problem.empty())
      s.warnings.push_back(std::string(kBlock) + ".private_key_file: " + problem);
  }
  s.inline_peers = read_peers(read(r2r, "peers"), base_dir);
  for (std::size_t i = 0; i < s.inline_peers.size(); ++i)
    s.inline_where.push_back("runtime.r2r.peers[" + std::to_string(i) + "]");
  if (const json file = read(r2r, "peers_file"); file.is_string()) s.peers_file = resolve(base_dir, file.get<std::string>());
  try {
    s.auth.peers = reload_peers(s);
  } catch (const std::exception& e) {
    bad("peers_file", e.what());
  }
  return s;
}

}  // namespace rcand::services::r2r
