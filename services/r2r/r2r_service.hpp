// R2R (seed 004, docs/protocol.md §11) assembled for the kernel: the transports runtime.r2r asks for (WebSocket on the HTTP
// port, UDP status, MQTT), the R2rNode fed with the robot's status and the Api's action path, and the thread that
// drives the node's clock work (status every interval). Off unless runtime.r2r.enabled. The auctions are the fleet
// plugin's (sdk::FleetAuctions): this service forwards /api/r2r/auction to it and reports its held tasks.
#pragma once

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "kernel/auth/authenticator.hpp"
#include "kernel/safety/estop.hpp"
#include "libs/config/robot_config.hpp"
#include "libs/http/handler.hpp"
#include "libs/http/server_options.hpp"
#include "libs/swarm/swarm_registry.hpp"
#include "rcand/sdk/clock.hpp"
#include "rcand/sdk/interfaces/fleet_auctions.hpp"
#include "rcand/sdk/interfaces/pose_source.hpp"
#include "services/r2r/r2r_node.hpp"

namespace rcand::services::r2r {

struct R2rServiceDeps {
  const config::RobotConfig& config;
  const kernel::Authenticator& authenticator;
  // POST /api/action as `principal`, through the kernel's middleware (Api::execute_action).
  std::function<void(const kernel::Principal&, nlohmann::json, std::function<void(int, nlohmann::json)>)> execute_action;
  std::function<std::string()> robot_state;  // idle | running | error | estop, as GET /api/status says it
  // nav's PoseSource (sdk::find over the plugins' services), looked up at each use: null while nothing offers it.
  std::function<const sdk::PoseSource*()> pose;
  const kernel::Estop& estop;
  const sdk::Clock& clock;
  std::function<const swarm::SwarmRegistry*()> swarm;  // swarm.yaml as now (a SIGHUP reload swaps it)
  std::string ruri;
  std::vector<std::string> capabilities;
  // The fleet plugin's auctions (sdk::find<sdk::FleetAuctions> over the plugins' services), looked up at each use:
  // null while nothing offers them (the plugin is not installed, not started yet, or failed).
  std::function<const sdk::FleetAuctions*()> fleet;
  // POST /api/stop as `principal` with `body` ({"reason","from"}), inline on the calling thread (the fleet e-stop,
  // docs/protocol.md §11.15): the same route, audit entry and latch as HTTP's, behind no queue.
  r2r::StopExecutor execute_stop;
};

class R2rService {
 public:
  // nullptr unless runtime.r2r.enabled is true. Throws StartupError naming the runtime.r2r key at fault.
  static std::unique_ptr<R2rService> from_config(R2rServiceDeps deps);
  ~R2rService();  // stop()

  // The HTTP server's upgrade hook (WS /ws/r2r). Call before the server starts.
  http::UpgradeHandler upgrade_handler();
  // After the HTTP server has bound `http_port`: binds UDP, connects MQTT, starts the node and its clock thread.
  // Throws StartupError naming the setting at fault.
  void start(std::uint16_t http_port);
  // First in shutdown (after the e-stop latch): no R2R message is handled or sent after it returns. Idempotent.
  void stop() noexcept;

  r2r::R2rNode& node() noexcept;
  // After a SIGHUP reload: runtime.r2r.peers_file (as named at startup) read again and swapped in whole. A file that
  // does not load keeps the table in force; the error, with its file:line:column, is logged.
  void reload_peers() noexcept;
  // The fleet plugin's auctions now, or null.
  const sdk::FleetAuctions* fleet() const;
  // {"name","peers":[...],"transports":{...},"counters":{...},"held_tasks":[...]}: GET /api/r2r/peers.
  nlohmann::json peers() const;
  // Hands POST /api/r2r/auction's `body` to `fleet`; its answer reaches `done` once, from any thread. stop() answers
  // every request still waiting 503 (rcand is shutting down) while HTTP still serves; fleet's later answer goes nowhere.
  void request_auction(const sdk::FleetAuctions& fleet, const nlohmann::json& body,
                       std::function<void(const sdk::Response&)> done);

  struct Impl;

 private:
  explicit R2rService(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace rcand::services::r2r
