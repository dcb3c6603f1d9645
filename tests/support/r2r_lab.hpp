// R2R integration-test helpers (header-only): robot configs with runtime.r2r on, the fleet's shared R2R token file,
// R2R messages built by hand (as a foreign peer would send them), and bounded polling of a robot's HTTP state.
#pragma once

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "libs/r2r_wire/message_signature.hpp"
#include "rcand_process.hpp"
#include "swarm_lab.hpp"
#include "ws_client.hpp"

namespace rcand::test {

// A sim robot named `name` at fleet position (x, y) speaking R2R with `token_file` (a token every robot accepts).
// UDP is off unless the test turns it on; bids are collected for bid_window_ms.
inline nlohmann::json r2r_robot_config(const std::string& name, const std::filesystem::path& token_file, double x = 0,
                                       double y = 0, const std::filesystem::path& swarm_file = {}) {
  auto config = swarm_robot_config(name, swarm_file);
  // nav offers the TripEstimator the default bid cost times a located task with; without it a robot declines those.
  config["rcan_protocol"]["capabilities"].push_back("nav");
  config["runtime"]["r2r"] = {{"enabled", true},       {"udp_enabled", false},      {"token_file", token_file.string()},
                              {"bid_window_ms", 1000}, {"status_interval_ms", 300}, {"origin", {{"x", x}, {"y", y}}}};
  return config;
}

// Ed25519 keys for a fleet: each robot signs with its own and accepts the others' (role USER). UDP and MQTT never
// carry the R2R token (issue 13 #10), so robots that talk over them authenticate by signature.
inline void sign_fleet(const std::vector<nlohmann::json*>& configs, const TempDir& dir) {
  std::vector<std::pair<std::string, std::filesystem::path>> public_keys;
  for (nlohmann::json* config : configs) {
    const std::string name = (*config)["metadata"]["robot_name"];
    const auto key = rcand::r2r_wire::Ed25519Key::generate();
    (*config)["runtime"]["r2r"]["private_key_file"] = dir.write(name + ".pem", key.private_pem()).string();
    public_keys.emplace_back(name, dir.write(name + ".pub.pem", key.public_pem()));
  }
  for (nlohmann::json* config : configs) {
    nlohmann::json peers = nlohmann::json::array();
    for (const auto& entry : public_keys)
      if (entry.first != (*config)["metadata"]["robot_name"])
        peers.push_back({{"name", entry.first}, {"public_key_file", entry.second.string()}, {"role", "USER"}});
    (*config)["runtime"]["r2r"]["peers"] = std::move(peers);
  }
}

inline double unix_now() { return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count(); }

// A message as a foreign peer writes it (no token: the WebSocket upgrade authenticated the sender).
inline std::string r2r_message(const std::string& source, const std::string& type, nlohmann::json payload,
                               const std::optional<std::string>& target = std::nullopt) {
  nlohmann::json header{{"version", "1.0"}, {"timestamp", unix_now()}, {"source_id", source}};
  if (target) header["target_id"] = *target;
  return nlohmann::json{{"header", header}, {"type", type}, {"payload", std::move(payload)}}.dump();
}

// Polls `probe` until it returns a value (or the deadline); the robots have no event a test could wait on.
template <class T>
std::optional<T> poll_until(const std::function<std::optional<T>()>& probe,
                            std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    if (auto value = probe()) return value;
    if (std::chrono::steady_clock::now() > deadline) return std::nullopt;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

// The peer entry `name` in GET /api/r2r/peers of `robot`, once it has a status from it.
inline std::optional<nlohmann::json> peer_status(const RcandProcess& robot, const std::string& name) {
  const auto doc = robot.json("GET", "/api/r2r/peers", "owner-token");
  if (!doc.is_object() || !doc.contains("peers")) return std::nullopt;
  for (const auto& peer : doc["peers"])
    if (peer["name"] == name && peer["status"].is_object()) return peer;
  return std::nullopt;
}

// peer_status() once that status gives a position: a robot serves (and sends its status) before its nav is up, and
// sends it again when the position is known.
inline std::optional<nlohmann::json> peer_status_placed(const RcandProcess& robot, const std::string& name) {
  auto peer = peer_status(robot, name);
  if (peer && (*peer)["status"].value("position", nlohmann::json()).is_object()) return peer;
  return std::nullopt;
}

// Frames until one satisfies `match` (status broadcasts and the like are skipped), or nullopt at the deadline.
inline std::optional<nlohmann::json> read_until(WsClient& client, const std::function<bool(const nlohmann::json&)>& match,
                                                std::chrono::milliseconds timeout = std::chrono::seconds(8)) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    auto frame = client.read(std::max(left, std::chrono::milliseconds(1)));
    if (!frame) return std::nullopt;
    nlohmann::json message = nlohmann::json::parse(*frame, nullptr, false);
    if (message.is_object() && match(message)) return message;
  }
  return std::nullopt;
}

// An R2R `error` message with `code`.
inline std::function<bool(const nlohmann::json&)> error_with(int code) {
  return [code](const nlohmann::json& m) { return m.value("type", "") == "error" && m["payload"].value("code", 0) == code; };
}

}  // namespace rcand::test
