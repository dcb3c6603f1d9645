#include "fleet_command.hpp"

#include <nlohmann/json.hpp>

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <optional>

#include "command_line.hpp"
#include "exit_codes.hpp"
#include "libs/r2r_wire/envelope.hpp"
#include "libs/r2r_wire/message_signature.hpp"
#include "libs/r2r_wire/peers_file.hpp"
#include "mqtt_publish_once.hpp"
#include "rcand/sdk/scope.hpp"

namespace rcand::rcanctl {
namespace {

using nlohmann::json;

struct FleetKeysOptions {
  std::string sub;
  bool as_json = false;
  // stop
  std::string key_file, sender, reason;
  MqttBrokerOptions mqtt;
  MqttBrokerFlags broker_flags;
  int timeout_s = 10;
  // keygen, enroll, revoke, list
  std::string name, out_dir = ".", peers_file, public_key, role = "USER";
  bool replace = false;
};

// A robot name as a file name and an MQTT topic level take it: no path separator, wildcard or blank.
std::string fleet_bad_name(const std::string& name) {
  if (name.empty()) return "NAME is empty";
  if (name.front() == '.' || name.front() == '-') return "NAME must not start with '.' or '-'";
  for (const unsigned char c : name)
    if (c <= ' ' || c == '/' || c == '\\' || c == '+' || c == '#' || c == 0x7f)
      return "NAME must not contain blanks, control characters, '/', '\\', '+' or '#'";
  return "";
}

std::optional<int> fleet_parse(std::span<const std::string> args, FleetKeysOptions& o, std::ostream& out, std::ostream& err) {
  const auto app =
      make_command_app("rcanctl fleet", "A fleet's keys and its e-stop over MQTT (README \"A fleet of ten robots\").",
                       "Exit: 0 done (stop: the broker acknowledged the e-stop), 1 failed, 2 usage error.\n"
                       "Example: rcanctl fleet stop --mqtt broker.lan --key ops.key --name ops --reason \"aisle 3 blocked\"");
  CLI::App* stop = app->add_subcommand(
      "stop",
      "sign a fleet e-stop (R2R command {\"type\":\"estop\"}) and publish it on r2r/broadcast; exit 0 once the "
      "broker acknowledged it (QoS 1). Every robot that has --name enrolled latches.");
  o.broker_flags.add_to(*stop, "HOST[:PORT]: the broker (port 1883, 8883 with --tls-ca-file)", true);
  stop->add_option("--key", o.key_file, "the sender's Ed25519 private key (PEM, from rcanctl fleet keygen)")->required();
  stop->add_option("--name", o.sender, "the sender's name: source_id and signature key_id, as enrolled in the peers file")
      ->required();
  stop->add_option("--reason", o.reason, "why: shown in every robot's e-stop reason and audit log");
  stop->add_option("--timeout", o.timeout_s, "seconds to wait for the broker (default 10)")->check(CLI::Range(1, 600));
  stop->add_flag("--json", o.as_json, "one JSON object");
  CLI::App* keygen = app->add_subcommand(
      "keygen",
      "make robot NAME's Ed25519 key pair: DIR/NAME.key (private, mode 600; runtime.r2r.private_key_file) and "
      "DIR/NAME.pub; never overwrites");
  keygen->add_option("NAME", o.name, "the robot's name (metadata.robot_name)")->required();
  keygen->add_option("--out", o.out_dir, "the directory to write in (default .)");
  CLI::App* enroll = app->add_subcommand(
      "enroll", "add robot NAME's public key to the fleet's peers file (runtime.r2r.peers_file), written atomically");
  enroll->add_option("NAME", o.name, "the robot's name: its source_id and signature key_id")->required();
  enroll->add_option("PUBLIC_KEY", o.public_key, "its public key: a file (PEM, e.g. NAME.pub) or 32 bytes in base64")->required();
  enroll->add_option("--role", o.role, "what its signed messages may do: GUEST, USER (default), LEASEE, OWNER, CREATOR");
  enroll->add_flag("--replace", o.replace, "replace NAME's key or role when it is enrolled with others");
  CLI::App* revoke = app->add_subcommand("revoke", "remove robot NAME from the peers file (written atomically)");
  revoke->add_option("NAME", o.name, "the robot's name")->required();
  CLI::App* list = app->add_subcommand("list", "the robots enrolled in the peers file");
  for (CLI::App* action : {enroll, revoke, list})
    action->add_option("--peers-file", o.peers_file, "the fleet's peers file (YAML)")->required();
  for (CLI::App* action : {keygen, enroll, revoke, list}) action->add_flag("--json", o.as_json, "one JSON object");
  app->require_subcommand(1);
  if (auto done = parse_command_line(*app, args, out, err)) return done;
  o.sub = app->get_subcommands().front()->get_name();
  if (o.sub == "stop") {
    if (auto bad = o.broker_flags.apply(o.mqtt)) return usage_error(*app, *bad, err);
    o.mqtt.timeout = std::chrono::seconds(o.timeout_s);
    o.mqtt.client_id = "rcanctl-fleet-stop-" + std::to_string(::getpid());
  }
  if (o.sub == "keygen" || o.sub == "enroll" || o.sub == "revoke")
    if (const auto bad = fleet_bad_name(o.name); !bad.empty()) return usage_error(*app, bad, err);
  if (o.sub == "enroll") {
    const auto role = sdk::parse_role(o.role);
    if (!role) return usage_error(*app, "--role must be GUEST, USER, LEASEE, OWNER or CREATOR, got '" + o.role + "'", err);
    o.role = std::string(sdk::role_name(*role));
  }
  return std::nullopt;
}

// Writes `text` to a new file `path` with `mode`; false (errno set) when it exists or cannot be made.
bool fleet_write_new(const std::filesystem::path& path, const std::string& text, mode_t mode) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, mode);
  if (fd < 0) return false;
  bool ok = ::fchmod(fd, mode) == 0;  // whatever the umask
  for (std::size_t done = 0; ok && done < text.size();) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    ok = n > 0;
    if (ok) done += static_cast<std::size_t>(n);
  }
  ok = ok && ::fsync(fd) == 0;
  const int saved = errno;
  ::close(fd);
  if (!ok) {
    ::unlink(path.c_str());
    errno = saved;
  }
  return ok;
}

int run_keygen(const FleetKeysOptions& o, std::ostream& out, std::ostream& err) {
  const std::filesystem::path dir = o.out_dir;
  const auto private_file = dir / (o.name + ".key");
  const auto public_file = dir / (o.name + ".pub");
  std::error_code ec;
  for (const auto& file : {private_file, public_file})
    if (std::filesystem::exists(file, ec)) {
      err << "rcanctl fleet keygen: " << file.string() << " exists; not overwritten (a robot's key is replaced on purpose: "
          << "move it away first)\n";
      return kExitFailure;
    }
  std::filesystem::create_directories(dir, ec);
  const r2r_wire::Ed25519Key key = r2r_wire::Ed25519Key::generate();
  if (!fleet_write_new(private_file, key.private_pem(), 0600)) {
    err << "rcanctl fleet keygen: cannot write " << private_file.string() << ": " << std::strerror(errno) << "\n";
    return kExitFailure;
  }
  if (!fleet_write_new(public_file, key.public_pem(), 0644)) {
    err << "rcanctl fleet keygen: cannot write " << public_file.string() << ": " << std::strerror(errno) << "\n";
    ::unlink(private_file.c_str());
    return kExitFailure;
  }
  if (o.as_json) {
    out << json{{"name", o.name},
                {"private_key_file", private_file.string()},
                {"public_key_file", public_file.string()},
                {"public_key", key.public_base64()}}
               .dump()
        << std::endl;
    return kExitOk;
  }
  out << "wrote " << private_file.string() << " (private key, mode 600): robot " << o.name
      << " only, as runtime.r2r.private_key_file\n"
      << "wrote " << public_file.string() << " (public key)\n"
      << "public key: " << key.public_base64() << "\n"
      << "next: rcanctl fleet enroll --peers-file PEERS.yaml " << o.name << " " << public_file.string() << "\n";
  return kExitOk;
}

// The peers file's directory, locked (flock) while one enroll or revoke reads and rewrites the file.
class PeersFileLock {
 public:
  explicit PeersFileLock(const std::filesystem::path& file) {
    const auto dir = file.has_parent_path() ? file.parent_path() : std::filesystem::path(".");
    fd_ = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd_ >= 0) ::flock(fd_, LOCK_EX);
  }
  ~PeersFileLock() {
    if (fd_ >= 0) ::close(fd_);
  }
  PeersFileLock(const PeersFileLock&) = delete;
  PeersFileLock& operator=(const PeersFileLock&) = delete;

 private:
  int fd_ = -1;
};

// The base64 public key of a peers-file entry (public_key, or public_key_file relative to the peers file).
std::string fleet_entry_key(const json& entry, const std::filesystem::path& peers_file) {
  if (entry.contains("public_key"))
    return r2r_wire::Ed25519Key::public_from_text(entry["public_key"].get<std::string>()).public_base64();
  std::filesystem::path file = entry["public_key_file"].get<std::string>();
  if (file.is_relative()) file = peers_file.parent_path() / file;
  return r2r_wire::Ed25519Key::public_from_file(file).public_base64();
}

int run_enroll(const FleetKeysOptions& o, std::ostream& out, std::ostream& err) {
  std::string key_base64;
  try {
    std::error_code ec;
    key_base64 = std::filesystem::is_regular_file(o.public_key, ec)
                     ? r2r_wire::Ed25519Key::public_from_file(o.public_key).public_base64()
                     : r2r_wire::Ed25519Key::public_from_text(o.public_key).public_base64();
  } catch (const std::exception& e) {
    err << "rcanctl fleet enroll: PUBLIC_KEY: " << e.what() << "\n";
    return kExitUsage;
  }
  try {
    PeersFileLock lock(o.peers_file);
    json doc = r2r_wire::read_peers_document(o.peers_file, true);
    json& peers = doc["peers"];
    const json entry{{"name", o.name}, {"public_key", key_base64}, {"role", o.role}};
    std::string action = "enrolled";
    auto it = std::find_if(peers.begin(), peers.end(), [&](const json& e) { return e["name"] == o.name; });
    if (it != peers.end()) {
      const std::string role = it->contains("role")
                                   ? std::string(sdk::role_name(*sdk::parse_role((*it)["role"].get<std::string>())))
                                   : std::string("USER");
      const bool same_key = fleet_entry_key(*it, o.peers_file) == key_base64;
      if (same_key && role == o.role) action = "already enrolled";
      else if (!o.replace) {
        err << "rcanctl fleet enroll: '" << o.name << "' is enrolled in " << o.peers_file << " with "
            << (same_key ? "" : "another key") << (!same_key && role != o.role ? " and " : "")
            << (role == o.role ? "" : "role " + role) << "; --replace to replace it\n";
        return kExitFailure;
      } else {
        *it = entry;
        action = "replaced";
      }
    } else {
      peers.push_back(entry);
    }
    if (action != "already enrolled") r2r_wire::write_peers_document(o.peers_file, doc);
    if (o.as_json)
      out << json{{"name", o.name},   {"role", o.role},       {"public_key", key_base64}, {"peers_file", o.peers_file},
                  {"action", action}, {"peers", peers.size()}}
                 .dump()
          << std::endl;
    else
      out << o.name << ": " << action << " in " << o.peers_file << " (" << o.role << ", " << peers.size()
          << " robots); copy it to every robot and send each rcand SIGHUP (systemctl reload rcand)\n";
  } catch (const std::exception& e) {
    err << "rcanctl fleet enroll: " << e.what() << "\n";
    return kExitFailure;
  }
  return kExitOk;
}

int run_revoke(const FleetKeysOptions& o, std::ostream& out, std::ostream& err) {
  try {
    PeersFileLock lock(o.peers_file);
    json doc = r2r_wire::read_peers_document(o.peers_file, false);
    json& peers = doc["peers"];
    const auto before = peers.size();
    peers.erase(std::remove_if(peers.begin(), peers.end(), [&](const json& e) { return e["name"] == o.name; }), peers.end());
    if (peers.size() == before) {
      err << "rcanctl fleet revoke: '" << o.name << "' is not enrolled in " << o.peers_file << "\n";
      return kExitFailure;
    }
    r2r_wire::write_peers_document(o.peers_file, doc);
    if (o.as_json)
      out << json{{"name", o.name}, {"peers_file", o.peers_file}, {"action", "revoked"}, {"peers", peers.size()}}.dump()
          << std::endl;
    else
      out << o.name << ": revoked from " << o.peers_file << " (" << peers.size()
          << " robots left); copy it to every robot and send each rcand SIGHUP\n";
  } catch (const std::exception& e) {
    err << "rcanctl fleet revoke: " << e.what() << "\n";
    return kExitFailure;
  }
  return kExitOk;
}

int run_list(const FleetKeysOptions& o, std::ostream& out, std::ostream& err) {
  json rows = json::array();
  try {
    const json doc = r2r_wire::read_peers_document(o.peers_file, false);
    for (const auto& entry : doc["peers"])
      rows.push_back(
          {{"name", entry["name"]},
           {"role", entry.contains("role") ? std::string(sdk::role_name(*sdk::parse_role(entry["role"].get<std::string>())))
                                           : std::string("USER")},
           {"public_key", fleet_entry_key(entry, o.peers_file)}});
  } catch (const std::exception& e) {
    err << "rcanctl fleet list: " << e.what() << "\n";
    return kExitFailure;
  }
  if (o.as_json) {
    out << json{{"peers_file", o.peers_file}, {"peers", rows}}.dump() << std::endl;
    return kExitOk;
  }
  out << std::left << std::setw(24) << "NAME" << std::setw(10) << "ROLE"
      << "PUBLIC KEY\n";
  for (const auto& row : rows)
    out << std::setw(24) << row["name"].get<std::string>() << std::setw(10) << row["role"].get<std::string>()
        << row["public_key"].get<std::string>() << "\n";
  return kExitOk;
}

int run_stop_over_mqtt(const FleetKeysOptions& o, std::ostream& out, std::ostream& err) {
  std::optional<r2r_wire::Ed25519Key> key;
  try {
    key.emplace(r2r_wire::Ed25519Key::private_from_file(o.key_file));
  } catch (const std::exception& e) {
    err << "rcanctl fleet stop: --key " << o.key_file << ": " << e.what() << "\n";
    return kExitUsage;
  }
  const double now = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  json payload{{"type", "estop"}};
  if (!o.reason.empty()) payload["reason"] = o.reason;
  json message{{"header", {{"version", std::string(r2r_wire::kProtocolVersion)}, {"timestamp", now}, {"source_id", o.sender}}},
               {"type", "command"},
               {"payload", payload}};
  r2r_wire::sign_message(message, o.sender, *key);
  const std::string topic = "r2r/broadcast";
  const MqttPublishResult result = mqtt_publish_once(o.mqtt, topic, message.dump());
  if (o.as_json) {
    json doc{{"published", result.acknowledged},
             {"broker", o.mqtt.host + ":" + std::to_string(o.mqtt.port)},
             {"topic", topic},
             {"sender", o.sender},
             {"reason", o.reason},
             {"elapsed_ms", result.elapsed_ms}};
    if (!result.acknowledged) doc["error"] = result.error;
    out << doc.dump() << std::endl;
  } else if (result.acknowledged) {
    out << "fleet e-stop from '" << o.sender << "' published on " << o.mqtt.host << ":" << o.mqtt.port << " " << topic
        << " (acknowledged in " << result.elapsed_ms << " ms); every robot that has '" << o.sender << "' enrolled latches\n";
  }
  if (!result.acknowledged) {
    err << "rcanctl fleet stop: " << result.error << "\n";
    return kExitFailure;
  }
  return kExitOk;
}

}  // namespace

int run_fleet(std::span<const std::string> args, std::ostream& out, std::ostream& err) {
  FleetKeysOptions options;
  if (auto done = fleet_parse(args, options, out, err)) return *done;
  if (options.sub == "keygen") return run_keygen(options, out, err);
  if (options.sub == "enroll") return run_enroll(options, out, err);
  if (options.sub == "revoke") return run_revoke(options, out, err);
  if (options.sub == "list") return run_list(options, out, err);
  return run_stop_over_mqtt(options, out, err);
}

int run_fleet(std::span<const std::string> args) { return run_fleet(args, std::cout, std::cerr); }

}  // namespace rcand::rcanctl
