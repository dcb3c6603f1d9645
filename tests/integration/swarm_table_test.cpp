// The swarm table (issue 18, services/swarm_broadcast/swarm_table.hpp) against real rcand processes: GET /api/swarm
// lists every node of swarm.yaml with its state (a dead one with a clear error, within the probe's bound), and
// POST /api/swarm/<node>/stop stops that node only - not the robot asked, not the others - audited, scoped like every
// stop (status), refusing an unknown node with 404 and reporting an unreachable one per node.
#include <doctest/doctest.h>

#include <chrono>

#include "libs/rcan/jwt.hpp"
#include "rcand_process.hpp"
#include "swarm_lab.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

// A node's row of GET /api/swarm; null when it is not listed.
json table_row(const json& table, const std::string& name) {
  for (const auto& row : table.value("nodes", json::array()))
    if (row.value("name", "") == name) return row;
  return nullptr;
}

bool latched(const RcandProcess& robot) { return robot.json("GET", "/api/estop", "guest-token").value("estopped", false); }

// A valid JWT whose scopes leave out `status` (a credential for control only).
std::string control_only_jwt() {
  rcand::JwtClaims claims;
  claims.sub = "narrow";
  claims.iss = "test";
  claims.role = "user";
  claims.aud = {"rcan://*"};
  claims.scope = {"control"};
  claims.iat = std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  claims.exp = claims.iat + 600;
  return rcand::issue_jwt_hs256(claims, kJwtSecret);
}

}  // namespace

TEST_CASE("swarm table: every node with its state; a per-node stop latches that node only, audited") {
  RcandProcess bravo(swarm_robot_config("bravo"));
  RcandProcess charlie(swarm_robot_config("charlie"));
  const auto dead_port = refused_port();
  TempDir dir;
  const auto swarm_file = dir.write("swarm.yaml", swarm_yaml({{"bravo", "127.0.0.1", bravo.port(), "owner-token", {"rover"}},
                                                              {"charlie", "127.0.0.1", charlie.port()},
                                                              {"dead", "127.0.0.1", dead_port}}));
  RcandProcess alpha(swarm_robot_config("alpha", swarm_file));

  const auto started = std::chrono::steady_clock::now();
  int status = 0;
  const json table = alpha.json("GET", "/api/swarm", "guest-token", {}, &status);
  CHECK(std::chrono::steady_clock::now() - started < std::chrono::seconds(2));  // bounded probes, not a TCP timeout
  REQUIRE(status == 200);
  CHECK(table["summary"] == json{{"total", 3}, {"reachable", 2}});
  const json b = table_row(table, "bravo");
  REQUIRE(b.is_object());
  CHECK(b["reachable"] == true);
  CHECK(b["estopped"] == false);
  CHECK(b["self"] == false);
  CHECK(b["tags"] == json{"rover"});
  CHECK(b["ruri"].get<std::string>().starts_with("rcan://"));
  const json d = table_row(table, "dead");
  REQUIRE(d.is_object());
  CHECK(d["reachable"] == false);
  CHECK(d["code"] == "SWARM_NODE_UNREACHABLE");
  CHECK_FALSE(d["error"].get<std::string>().empty());
  CHECK(table.dump().find("owner-token") == std::string::npos);  // the nodes' tokens never leave the robot

  const json stopped = alpha.json("POST", "/api/swarm/bravo/stop", "guest-token", R"({"reason":"test"})", &status);
  REQUIRE(status == 200);
  CHECK(stopped["node"]["name"] == "bravo");
  CHECK(stopped["node"]["motors_stopped"] == true);
  CHECK(latched(bravo));
  CHECK_FALSE(latched(alpha));    // the robot asked is not stopped ...
  CHECK_FALSE(latched(charlie));  // ... nor any other node
  CHECK(bravo.json("GET", "/api/estop", "guest-token")["reason"].get<std::string>().find("swarm table") != std::string::npos);
  CHECK(table_row(alpha.json("GET", "/api/swarm", "guest-token"), "bravo")["estopped"] == true);

  bool audited = false;
  const json audit = alpha.json("GET", "/api/audit", "owner-token");
  for (const auto& entry : audit["entries"])
    if (entry["event"] == "POST /api/swarm/bravo/stop") audited = entry["outcome"] == "ok";
  INFO(audit.dump());
  CHECK(audited);
  const std::string page = alpha.request("GET", "/metrics", "guest-token").body;
  CHECK(page.find("rcand_swarm_node_results_total{kind=\"node_stop\",outcome=\"ok\"} 1\n") != std::string::npos);
}

TEST_CASE("swarm table: unknown node 404, no status scope 403, an unreachable node is that node's error") {
  RcandProcess bravo(swarm_robot_config("bravo"));
  TempDir dir;
  const auto swarm_file =
      dir.write("swarm.yaml", swarm_yaml({{"bravo", "127.0.0.1", bravo.port()}, {"dead", "127.0.0.1", refused_port()}}));
  RcandProcess alpha(swarm_robot_config("alpha", swarm_file));

  int status = 0;
  json answer = alpha.json("POST", "/api/swarm/nobody/stop", "guest-token", {}, &status);
  CHECK(status == 404);
  CHECK(answer["code"] == "SWARM_NODE_NOT_FOUND");
  CHECK(answer["known_nodes"] == json{"bravo", "dead"});
  answer = alpha.json("POST", "/api/swarm/bravo/halt", "guest-token", {}, &status);
  CHECK(status == 404);
  CHECK(answer["code"] == "NOT_FOUND");

  answer = alpha.json("POST", "/api/swarm/bravo/stop", control_only_jwt(), {}, &status);
  CHECK(status == 403);
  CHECK(answer["required_scope"] == "status");
  CHECK(alpha.request("POST", "/api/swarm/bravo/stop").status == 401);
  CHECK(alpha.json("GET", "/api/swarm", control_only_jwt(), {}, &status).is_object());
  CHECK(status == 403);
  CHECK_FALSE(latched(bravo));  // nothing refused reached it

  answer = alpha.json("POST", "/api/swarm/dead/stop", "guest-token", {}, &status);
  CHECK(status == 502);
  CHECK(answer["code"] == "SWARM_NODE_UNREACHABLE");
  CHECK(answer["error"].get<std::string>().find("node 'dead' could not be reached") == 0);
  CHECK(answer["node"]["name"] == "dead");
  CHECK(answer["node"]["http_status"].is_null());
  CHECK_FALSE(latched(alpha));
  CHECK_FALSE(latched(bravo));
}
