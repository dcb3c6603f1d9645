#include "libs/r2r_wire/peers_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>

#include "libs/yaml/json_to_yaml.hpp"
#include "libs/yaml/yaml_document.hpp"

namespace rcand::r2r_wire {
namespace {

using nlohmann::json;

struct PeersDocument {
  json doc;
  std::map<std::string, yaml::SourceMark> marks;
  std::string display;
};

[[noreturn]] void peers_fault(const PeersDocument& d, const std::string& key_path, const std::string& message) {
  yaml::ConfigDiagnostic diagnostic;
  diagnostic.mark = yaml::nearest_mark(d.marks, d.display, key_path);
  diagnostic.key_path = key_path;
  diagnostic.message = message;
  throw std::invalid_argument(diagnostic.format());
}

// Parses and checks the shape; `missing_ok`: a file that does not exist is an empty list.
PeersDocument read_peers_checked(const std::filesystem::path& file, bool missing_ok) {
  PeersDocument d;
  d.display = file.string();
  std::error_code ec;
  if (missing_ok && !std::filesystem::exists(file, ec)) {
    d.doc = {{"peers", json::array()}};
    return d;
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::invalid_argument(d.display + ": cannot read the peers file: " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  std::vector<yaml::ConfigDiagnostic> diagnostics;
  yaml::YamlDocument parsed = yaml::yaml_to_json(text.str(), d.display, diagnostics);
  for (const auto& diagnostic : diagnostics)
    if (diagnostic.severity == yaml::ConfigDiagnostic::Severity::Error) throw std::invalid_argument(diagnostic.format());
  if (!parsed.ok) throw std::invalid_argument(d.display + ": not a YAML document");
  d.doc = std::move(parsed.doc);
  d.marks = std::move(parsed.marks);
  if (parsed.empty || !d.doc.is_object()) peers_fault(d, "", "expected a mapping with `peers:` (a list of robots)");
  for (const auto& [key, value] : d.doc.items())
    if (key != "peers") peers_fault(d, key, "unknown key '" + key + "' (the file holds `peers:` only)");
  if (!d.doc.contains("peers") || d.doc["peers"].is_null()) d.doc["peers"] = json::array();
  if (!d.doc["peers"].is_array()) peers_fault(d, "peers", "expected a list of robots");
  std::map<std::string, std::size_t> names;
  for (std::size_t i = 0; i < d.doc["peers"].size(); ++i) {
    const json& entry = d.doc["peers"][i];
    const std::string at = yaml::item_path("peers", i);
    if (!entry.is_object()) peers_fault(d, at, "expected a mapping {name, public_key or public_key_file, role}");
    for (const auto& [key, value] : entry.items()) {
      if (key != "name" && key != "public_key" && key != "public_key_file" && key != "role")
        peers_fault(d, yaml::child_path(at, key), "unknown key '" + key + "' (name, public_key, public_key_file, role)");
      if (!value.is_string() || value.get_ref<const std::string&>().empty())
        peers_fault(d, yaml::child_path(at, key), "expected a non-empty string");
    }
    if (!entry.contains("name")) peers_fault(d, at, "name is required");
    if (entry.contains("public_key") == entry.contains("public_key_file"))
      peers_fault(d, at, "give exactly one of public_key and public_key_file");
    if (entry.contains("role") && !sdk::parse_role(entry["role"].get<std::string>()))
      peers_fault(d, yaml::child_path(at, "role"), "expected GUEST, USER, LEASEE, OWNER or CREATOR");
    const std::string name = entry["name"].get<std::string>();
    if (const auto [it, fresh] = names.emplace(name, i); !fresh)
      peers_fault(d, yaml::child_path(at, "name"),
                  "'" + name + "' is enrolled twice (also " + yaml::item_path("peers", it->second) + ")");
  }
  return d;
}

}  // namespace

LoadedPeers load_peers_file(const std::filesystem::path& file) {
  const PeersDocument d = read_peers_checked(file, false);
  LoadedPeers out;
  for (std::size_t i = 0; i < d.doc["peers"].size(); ++i) {
    const json& entry = d.doc["peers"][i];
    const std::string at = yaml::item_path("peers", i);
    PeerKey peer;
    peer.name = entry["name"].get<std::string>();
    peer.role = entry.contains("role") ? *sdk::parse_role(entry["role"].get<std::string>()) : sdk::Role::User;
    const bool has_file = entry.contains("public_key_file");
    const std::string key = has_file ? "public_key_file" : "public_key";
    try {
      std::filesystem::path key_file = has_file ? entry[key].get<std::string>() : std::string();
      if (has_file && key_file.is_relative()) key_file = file.parent_path() / key_file;
      peer.key = std::make_shared<const Ed25519Key>(has_file ? Ed25519Key::public_from_file(key_file)
                                                             : Ed25519Key::public_from_text(entry[key].get<std::string>()));
    } catch (const std::exception& e) {
      peers_fault(d, yaml::child_path(at, key), e.what());
    }
    const yaml::SourceMark mark = yaml::nearest_mark(d.marks, d.display, at);
    out.where.push_back(mark.file + ":" + std::to_string(mark.line) + ":" + std::to_string(mark.column));
    out.peers.push_back(std::move(peer));
  }
  return out;
}

std::vector<PeerKey> merge_peers(std::vector<PeerKey> inline_peers, const std::vector<std::string>& inline_where,
                                 LoadedPeers from_file) {
  for (std::size_t i = 0; i < from_file.peers.size(); ++i)
    for (std::size_t j = 0; j < inline_peers.size(); ++j)
      if (inline_peers[j].name == from_file.peers[i].name)
        throw std::invalid_argument("peer '" + inline_peers[j].name + "' is both in " +
                                    (j < inline_where.size() ? inline_where[j] : "runtime.r2r.peers") +
                                    " and in the peers file at " + from_file.where[i] + ": keep one");
  for (auto& peer : from_file.peers) inline_peers.push_back(std::move(peer));
  return inline_peers;
}

json read_peers_document(const std::filesystem::path& file, bool missing_ok) { return read_peers_checked(file, missing_ok).doc; }

void write_peers_document(const std::filesystem::path& file, const json& doc) {
  const std::filesystem::path dir = file.has_parent_path() ? file.parent_path() : std::filesystem::path(".");
  std::string temp = (dir / ("." + file.filename().string() + ".XXXXXX")).string();
  const int fd = ::mkstemp(temp.data());
  if (fd < 0) throw std::runtime_error("cannot write in " + dir.string() + ": " + std::strerror(errno));
  const std::string text =
      "# The fleet's enrolled robots (runtime.r2r.peers_file), written by rcanctl fleet enroll.\n" + yaml::json_to_yaml(doc);
  bool ok = ::fchmod(fd, 0644) == 0;
  for (std::size_t done = 0; ok && done < text.size();) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    ok = n > 0;
    if (ok) done += static_cast<std::size_t>(n);
  }
  const int saved = errno;
  ok = ok && ::fsync(fd) == 0;
  ::close(fd);
  if (!ok || ::rename(temp.c_str(), file.c_str()) != 0) {
    const std::string why = std::strerror(ok ? errno : saved);
    ::unlink(temp.c_str());
    throw std::runtime_error("cannot write " + file.string() + ": " + why);
  }
  // The rename is durable once the directory is.
  if (const int dir_fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY); dir_fd >= 0) {
    ::fsync(dir_fd);
    ::close(dir_fd);
  }
}

}  // namespace rcand::r2r_wire
