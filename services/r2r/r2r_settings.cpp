#include "services/r2r/r2r_settings.hpp"

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace rcand::kernel::r2r {
namespace {

using nlohmann::json;

[[noreturn]] void bad(const std::string& key, const std::string& message) {
  throw std::invalid_argument("runtime.r2r." + key + ": " + message);
}

double number_at(const json& block, const char* key, const std::string& path, double fallback) {
  const auto it = block.find(key);
  if (it == block.end() || it->is_null()) return fallback;
  if (!it->is_number() || !std::isfinite(it->get<double>())) bad(path, "expected a finite number");
  return it->get<double>();
}

std::filesystem::path resolve(const std::filesystem::path& base, const std::string& file) {
  const std::filesystem::path p(file);
  return p.is_absolute() ? p : base / p;
}

std::string read_secret_file(const std::filesystem::path& file, const std::string& key) {
  std::ifstream in(file, std::ios::binary);
  if (!in) bad(key, "cannot read " + file.string());
  std::ostringstream text;
  text << in.rdbuf();
  std::string token = text.str();
  while (!token.empty() && (token.back() == '\n' || token.back() == '\r' || token.back() == ' ')) token.pop_back();
  if (token.empty()) bad(key, file.string() + " is empty");
  return token;
}

}  // namespace

R2rSettings load_r2r_settings(const json& r2r, const std::filesystem::path& base_dir) {
  R2rSettings s;
  if (r2r.is_null()) return s;
  if (!r2r.is_object()) throw std::invalid_argument("runtime.r2r: expected a mapping");

  if (const auto origin = r2r.find("origin"); origin != r2r.end() && !origin->is_null()) {
    if (!origin->is_object()) bad("origin", "expected a mapping {x, y, heading_deg}");
    s.origin = {number_at(*origin, "x", "origin.x", 0.0), number_at(*origin, "y", "origin.y", 0.0),
                number_at(*origin, "heading_deg", "origin.heading_deg", 0.0)};
  }
  const auto positive_ms = [&](const char* key, std::chrono::milliseconds fallback) {
    const double v = number_at(r2r, key, key, static_cast<double>(fallback.count()));
    if (v <= 0 || v > 3'600'000) bad(key, "expected milliseconds in (0, 3600000]");
    return std::chrono::milliseconds(static_cast<std::int64_t>(v));
  };
  s.status_interval = positive_ms("status_interval_ms", s.status_interval);
  s.bid_window = positive_ms("bid_window_ms", s.bid_window);
  s.seconds_per_task = number_at(r2r, "cost_per_queued_task_s", "cost_per_queued_task_s", s.seconds_per_task);
  if (s.seconds_per_task < 0) bad("cost_per_queued_task_s", "expected a number >= 0");
  s.auth.replay_window_s = number_at(r2r, "replay_window_s", "replay_window_s", s.auth.replay_window_s);
  if (s.auth.replay_window_s <= 0) bad("replay_window_s", "expected a number > 0");
  const auto count_at = [&](const char* key, std::size_t fallback) {
    const double v = number_at(r2r, key, key, static_cast<double>(fallback));
    if (v < 1 || v > 1'000'000 || v != std::floor(v)) bad(key, "expected an integer from 1 to 1000000");
    return static_cast<std::size_t>(v);
  };
  s.max_peers = count_at("max_peers", s.max_peers);
  s.bidder.max_held_tasks = count_at("max_held_tasks", s.bidder.max_held_tasks);
  s.peer_expiry_s = number_at(r2r, "peer_expiry_s", "peer_expiry_s", s.peer_expiry_s);
  if (s.peer_expiry_s <= 0) bad("peer_expiry_s", "expected a number of seconds > 0");

  if (const auto require = r2r.find("require_signatures"); require != r2r.end()) {
    if (!require->is_boolean()) bad("require_signatures", "expected true or false");
    s.auth.require_signatures = require->get<bool>();
  }
  if (const auto file = r2r.find("token_file"); file != r2r.end()) {
    if (!file->is_string() || file->get_ref<const std::string&>().empty()) bad("token_file", "expected a file name");
    s.outbound_token = read_secret_file(resolve(base_dir, file->get<std::string>()), "token_file");
  }
  if (const auto file = r2r.find("private_key_file"); file != r2r.end()) {
    if (!file->is_string() || file->get_ref<const std::string&>().empty()) bad("private_key_file", "expected a file name");
    try {
      s.private_key =
          std::make_shared<const Ed25519Key>(Ed25519Key::private_from_file(resolve(base_dir, file->get<std::string>())));
    } catch (const std::exception& e) {
      bad("private_key_file", e.what());
    }
  }
  if (const auto peers = r2r.find("peers"); peers != r2r.end()) {
    if (!peers->is_array()) bad("peers", "expected a sequence of {name, public_key_file | public_key, role}");
    for (std::size_t i = 0; i < peers->size(); ++i) {
      const json& entry = (*peers)[i];
      const std::string at = "peers[" + std::to_string(i) + "]";
      if (!entry.is_object()) bad(at, "expected a mapping {name, public_key_file | public_key, role}");
      PeerKey peer;
      if (!entry.contains("name") || !entry["name"].is_string() || entry["name"].get_ref<const std::string&>().empty())
        bad(at + ".name", "required: the peer's robot name (its key_id)");
      peer.name = entry["name"].get<std::string>();
      for (const PeerKey& earlier : s.auth.peers)
        if (earlier.name == peer.name) bad(at + ".name", "'" + peer.name + "' is listed twice");
      if (const auto role = entry.find("role"); role != entry.end()) {
        const auto parsed = role->is_string() ? sdk::parse_role(role->get_ref<const std::string&>()) : std::nullopt;
        if (!parsed) bad(at + ".role", "expected GUEST, USER, LEASEE, OWNER or CREATOR");
        peer.role = *parsed;
      }
      const bool has_file = entry.contains("public_key_file"), has_inline = entry.contains("public_key");
      if (has_file == has_inline) bad(at, "give exactly one of public_key_file and public_key");
      const std::string key = has_file ? "public_key_file" : "public_key";
      if (!entry[key].is_string()) bad(at + "." + key, "expected a string");
      try {
        peer.key = std::make_shared<const Ed25519Key>(
            has_file ? Ed25519Key::public_from_file(resolve(base_dir, entry[key].get<std::string>()))
                     : Ed25519Key::public_from_text(entry[key].get<std::string>()));
      } catch (const std::exception& e) {
        bad(at + "." + key, e.what());
      }
      s.auth.peers.push_back(std::move(peer));
    }
  }
  if (s.auth.require_signatures && !s.private_key)
    bad("require_signatures", "signatures are required, so private_key_file must be set (this robot signs too)");
  return s;
}

}  // namespace rcand::kernel::r2r
