// Swarm integration-test helpers (header-only): swarm.yaml files for rcand processes, a port that accepts and never
// answers, and a port that refuses.
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>

#include <cstdint>
#include <deque>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "rcand_process.hpp"

namespace rcand::test {

struct SwarmEntry {
  SwarmEntry(std::string name_, std::string host_, std::uint16_t port_, std::string token_ = "owner-token",
             std::vector<std::string> tags_ = {}, std::string ip_ = {})
      : name(std::move(name_)), host(std::move(host_)), port(port_), token(std::move(token_)), tags(std::move(tags_)),
        ip(std::move(ip_)) {}
  std::string name;
  std::string host;
  std::uint16_t port = 0;
  std::string token;
  std::vector<std::string> tags;
  std::string ip;  // optional fallback
};

inline std::string swarm_yaml(const std::vector<SwarmEntry>& entries) {
  std::string text = "# written by a swarm integration test\nnodes:\n";
  for (const auto& e : entries) {
    text += "  - name: \"" + e.name + "\"\n    host: \"" + e.host + "\"\n    port: " + std::to_string(e.port) +
            "\n    token: \"" + e.token + "\"\n";
    if (!e.ip.empty()) text += "    ip: \"" + e.ip + "\"\n";
    if (!e.tags.empty()) {
      text += "    tags: [";
      for (std::size_t i = 0; i < e.tags.size(); ++i) text += (i ? ", " : "") + e.tags[i];
      text += "]\n";
    }
  }
  return text;
}

// The sim robot's config named `name`, with its swarm file (when given).
inline nlohmann::json swarm_robot_config(const std::string& name, const std::filesystem::path& swarm_file = {}) {
  auto config = sim_config();
  config["metadata"]["robot_name"] = name;
  if (!swarm_file.empty()) config["runtime"]["swarm_file"] = swarm_file.string();
  else config["runtime"]["swarm_file"] = "/nonexistent/rcand-test/swarm.yaml";  // never the machine's /etc/rcand
  return config;
}

// Completes TCP handshakes (the kernel's listen backlog) and never reads or answers: a hung robot.
class SilentPort {
 public:
  SilentPort() : acceptor_(io_, boost::asio::ip::tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), 0)) {}
  std::uint16_t port() const { return acceptor_.local_endpoint().port(); }

 private:
  boost::asio::io_context io_;
  boost::asio::ip::tcp::acceptor acceptor_;
};

// The entry of node `name` in a swarm report ({"nodes": [...]}); throws (failing the test) when there is none.
inline nlohmann::json node_named(const nlohmann::json& report, const std::string& name) {
  for (const auto& node : report.value("nodes", nlohmann::json::array()))
    if (node.value("name", "") == name) return node;
  throw std::runtime_error("no node '" + name + "' in " + report.dump());
}

// A loopback port nobody listens on: connections are refused. The port stays bound (never listening, without
// SO_REUSEADDR) for the test process's life, so no robot started later can be given it by bind(0) - a released port
// once came back as the robot's own, which then left the "dead" node out of its broadcast as itself.
inline std::uint16_t refused_port() {
  static boost::asio::io_context io;
  static std::deque<boost::asio::ip::tcp::socket> held;
  auto& socket = held.emplace_back(io);
  socket.open(boost::asio::ip::tcp::v4());
  socket.bind(boost::asio::ip::tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), 0));
  return socket.local_endpoint().port();
}

}  // namespace rcand::test
