// The swarm table (the dashboard's fleet view, issue 18): every node of runtime.swarm_file with its state when it
// answers, and a stop for one node at a time. Both go through the broadcasts' fan-out client (libs/swarm/fan_out),
// with each node's own token from swarm.yaml, never to this robot's server threads' cost:
//   GET  /api/swarm              (status)  {"nodes":[{"name","address","tags","self","reachable","http_status",
//                                          "state","estopped","ruri","latency_ms","error"?,"code"?}],"summary":{...}}
//                                          each node probed with GET /api/status, 300 ms at most, all at once
//   POST /api/swarm/<name>/stop  (status, audited, never rate-limited, like every stop)  POST /api/stop on that node
//                                          only, marked forwarded (it never spreads further) -> 200 {"node": entry}
//                                          (swarm::node_entry); 404 SWARM_NODE_NOT_FOUND (known_nodes); 502
//                                          SWARM_NODE_UNREACHABLE or SWARM_NODE_FAILED with the node's entry
// This robot is listed too ("self": true) and is not stopped by a per-node stop of another node.
#pragma once

#include "kernel/service.hpp"
#include "libs/swarm/fan_out.hpp"

namespace rcand::services {

// Whether `node` of swarm.yaml is this robot (its address is this robot's listen address or loopback, at its port).
bool is_this_robot(const swarm::SwarmNode& node, const kernel::ServiceHost& host);

class SwarmTable {
 public:
  SwarmTable(kernel::ServiceHost& host, swarm::FanOut& fan_out) : host_(host), fan_out_(fan_out) {}
  void add_routes(kernel::Router& router);

 private:
  void list(kernel::Call& call, kernel::Reply reply);
  void stop_node(kernel::Call& call, kernel::Reply reply);

  kernel::ServiceHost& host_;
  swarm::FanOut& fan_out_;
};

}  // namespace rcand::services
