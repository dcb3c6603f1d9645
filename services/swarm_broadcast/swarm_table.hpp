// The swarm table (the dashboard's fleet view, issue 18): every node of runtime.swarm_file with its state when it
// answers, and a stop for one node at a time. Both go through the broadcasts' fan-out client (libs/swarm/fan_out),
// with each node's own token from swarm.yaml, never to this robot's server threads' cost:
//   GET  /api/swarm              (status)  {"nodes":[{"name","address","tags","self","reachable","http_status",
//                                          "state","estopped","ruri","latency_ms","error"?,"code"?}],"summary":{...}}
//                                          each node probed with GET /api/status, 300 ms at most, all at once
//   POST /api/swarm/<name>/stop  (status, audited as a stop, never rate-limited, like every stop)  POST /api/stop on
//                                          that node only, marked forwarded (it never spreads further) -> 200
//                                          {"node": entry} (swarm::node_entry); 502 SWARM_NODE_UNREACHABLE or
//                                          SWARM_NODE_FAILED with the node's entry; a node not in swarm.yaml (or a
//                                          path that is no node's stop) is no stop: 404 SWARM_NODE_NOT_FOUND
//                                          (known_nodes), audited, at most kUnknownNodePerSecond a second per
//                                          principal (burst kUnknownNodeBurst), then 429 RATE_LIMITED, logged only
// This robot is listed too ("self": true) and is not stopped by a per-node stop of another node.
#pragma once

#include "kernel/service.hpp"
#include "libs/base/logging.hpp"
#include "libs/base/rate_limiter.hpp"
#include "libs/swarm/fan_out.hpp"
#include "libs/swarm/live_registry.hpp"

namespace rcand::services {

// Whether `node` of swarm.yaml is this robot (its address is this robot's listen address or loopback, at its port).
bool is_this_robot(const swarm::SwarmNode& node, const kernel::ServiceHost& host);

class SwarmTable {
 public:
  static constexpr double kUnknownNodePerSecond = 2;
  static constexpr double kUnknownNodeBurst = 10;

  SwarmTable(kernel::ServiceHost& host, const swarm::LiveRegistry& swarm, swarm::FanOut& fan_out)
      : host_(host), swarm_(swarm), fan_out_(fan_out) {}
  void add_routes(kernel::Router& router);

 private:
  void list(kernel::Call& call, kernel::Reply reply);
  void stop_node(kernel::Call& call, kernel::Reply reply);

  void refuse_unknown(kernel::Call& call, const kernel::Reply& reply, bool shaped, const std::string& name);

  kernel::ServiceHost& host_;
  const swarm::LiveRegistry& swarm_;
  swarm::FanOut& fan_out_;
  // Unknown-node refusals per principal (issue 28 #7: they were audited without limit); stops are never limited.
  RateLimiter unknown_node_limit_{{kUnknownNodePerSecond, kUnknownNodeBurst / kUnknownNodePerSecond}};
  LogRateLimiter refusal_log_{5};
};

}  // namespace rcand::services
