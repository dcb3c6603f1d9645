// §15 swarm against real rcand processes on the sim drive: broadcast stop and command fanned out node by node,
// per-node reporting with partial failure, the e-stop acknowledgement, no re-forwarding, each node's own scope
// checks, and rcanctl. Dead robots are a refused port and a port that accepts and never answers.
#include <doctest/doctest.h>

#include <signal.h>

#include <chrono>
#include <memory>

#include "eventually.hpp"
#include "netns_lab.hpp"
#include "rcand_process.hpp"
#include "sanitized_build.hpp"
#include "swarm_lab.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

const std::string kSwarmMove = R"({"type":"move","linear":0.5,"angular":0.0,"duration_ms":5000})";
const std::map<std::string, std::string> kBroadcast{{"X-Swarm-Broadcast", "true"}};

int count_events(const RcandProcess& robot, const std::string& event) {
  int n = 0;
  const json audit = robot.json("GET", "/api/audit?limit=1000", "owner-token");  // kept alive for the loop
  for (const auto& entry : audit["entries"])
    if (entry["event"] == event) ++n;
  return n;
}

json post(const RcandProcess& robot, const std::string& target, const std::string& token, const std::string& body,
          std::map<std::string, std::string> headers, int* status) {
  auto response = robot.request("POST", target, token, body, std::move(headers));
  if (status) *status = response.status;
  return json::parse(response.body, nullptr, false);
}

}  // namespace

TEST_CASE(
    "swarm: a broadcast stop halts this robot first, then every reachable node; dead ones are reported, all inside 500 ms") {
  TempDir dir;
  RcandProcess b(swarm_robot_config("bravo"));
  RcandProcess c(swarm_robot_config("charlie"));
  SilentPort silent;
  const auto refused = refused_port();
  const auto swarm_file = dir.write("swarm.yaml", swarm_yaml({{"bravo", "127.0.0.1", b.port()},
                                                              {"charlie", "127.0.0.1", c.port()},
                                                              {"silent", "127.0.0.1", silent.port()},
                                                              {"refused", "127.0.0.1", refused}}));
  RcandProcess a(swarm_robot_config("alpha", swarm_file));
  int status = 0;
  for (const RcandProcess* robot : {&a, &b, &c}) {
    robot->json("POST", "/api/action", "user-token", kSwarmMove, &status);
    REQUIRE(status == 200);
    REQUIRE(drive_status(*robot)["moving"] == true);
  }

  const auto before = std::chrono::steady_clock::now();
  auto report = post(a, "/api/stop", "guest-token", "", kBroadcast, &status);  // a stop needs only scope status
  const auto elapsed = std::chrono::steady_clock::now() - before;
  REQUIRE(status == 200);
  CHECK(elapsed < std::chrono::milliseconds(500));  // §15.5 MUST, with a silent node in the swarm
  INFO(report.dump(2));
  CHECK(report["broadcast"] == true);
  CHECK(report["status"] == "stopped");  // the local stop's own fields stay at the top
  CHECK(report["motors_stopped"] == true);
  REQUIRE(report["nodes"].size() == 5);
  CHECK(report["summary"] == json{{"total", 5}, {"ok", 3}, {"failed", 2}});
  CHECK(report["nodes"][0]["name"] == "alpha");
  CHECK(report["nodes"][0]["local"] == true);
  for (const char* name : {"alpha", "bravo", "charlie"}) {
    const auto node = node_named(report, name);
    CHECK(node["ok"] == true);
    CHECK(node["executed"] == true);
    CHECK(node["http_status"] == 200);
    CHECK(node["motors_stopped"] == true);
    CHECK(node["error"].is_null());
    CHECK(node["latency_ms"].is_number());
  }
  const auto hung = node_named(report, "silent");
  CHECK(hung["ok"] == false);
  CHECK(hung["http_status"].is_null());
  CHECK(hung["error"].get<std::string>().find("timed out") != std::string::npos);
  const auto dead = node_named(report, "refused");
  CHECK(dead["ok"] == false);
  CHECK(dead["error"].get<std::string>().find("cannot connect") != std::string::npos);

  // Every reachable robot's motors are at zero and its e-stop is latched.
  for (const RcandProcess* robot : {&a, &b, &c}) {
    const auto motors = drive_status(*robot);
    CHECK(motors["moving"] == false);
    CHECK(motors["left"] == 0.0);
    CHECK(motors["right"] == 0.0);
    CHECK(robot->json("GET", "/api/estop", "guest-token")["estopped"] == true);
  }
  CHECK(b.json("GET", "/api/estop", "guest-token")["reason"].get<std::string>().find("swarm broadcast from rcan://") == 0);

  // The peers' tokens from swarm.yaml are never logged, by the origin or by the peers.
  for (const RcandProcess* robot : {&a, &b, &c}) CHECK(robot->stderr_text().find("owner-token") == std::string::npos);

  // Local first: alpha's halt is on the timeline (one steady clock for the whole machine) before the peers even
  // received the forwarded stop.
  const auto alpha_halt = drive_status(a)["timeline"].back();
  CHECK(alpha_halt["cause"] == "halt");
  for (const char* name : {"bravo", "charlie"})
    CHECK(alpha_halt["t_us"].get<std::int64_t>() <= node_named(report, name)["response"]["received_us"].get<std::int64_t>());
}

TEST_CASE("swarm: a broadcast command reports each node; a node in e-stop acknowledges without executing") {
  TempDir dir;
  RcandProcess b(swarm_robot_config("bravo"));
  RcandProcess c(swarm_robot_config("charlie"));
  const auto refused = refused_port();
  const auto swarm_file = dir.write("swarm.yaml", swarm_yaml({{"bravo", "127.0.0.1", b.port(), "user-token"},
                                                              {"charlie", "127.0.0.1", c.port(), "user-token"},
                                                              {"refused", "127.0.0.1", refused}}));
  RcandProcess a(swarm_robot_config("alpha", swarm_file));
  int status = 0;
  c.json("POST", "/api/stop", "guest-token", "", &status);
  REQUIRE(status == 200);

  // The body's "broadcast": true is the same signal as the header.
  for (bool by_header : {true, false}) {
    CAPTURE(by_header);
    const std::string body = by_header ? R"({"instruction":"go forward"})" : R"({"instruction":"go forward","broadcast":true})";
    auto report =
        post(a, "/api/command", "user-token", body, by_header ? kBroadcast : std::map<std::string, std::string>{}, &status);
    REQUIRE(status == 200);
    INFO(report.dump(2));
    REQUIRE(report["nodes"].size() == 4);
    CHECK(report["summary"] == json{{"total", 4}, {"ok", 1}, {"failed", 3}});
    // No robot here has chat: §9.1 answers 404 CAPABILITY_NOT_FOUND, reported per node.
    for (const char* name : {"alpha", "bravo"}) {
      const auto node = node_named(report, name);
      CHECK(node["ok"] == false);
      CHECK(node["executed"] == false);
      CHECK(node["http_status"] == 404);
      CHECK(node["code"] == "CAPABILITY_NOT_FOUND");
    }
    const auto estopped = node_named(report, "charlie");
    CHECK(estopped["ok"] == true);
    CHECK(estopped["executed"] == false);
    CHECK(estopped["http_status"] == 200);
    CHECK(estopped["reason"] == "estop_active");
    CHECK(estopped["response"] == json{{"ack", true}, {"executed", false}, {"reason", "estop_active"}});
    CHECK(node_named(report, "refused")["ok"] == false);
  }
  CHECK(drive_status(c)["moving"] == false);
  CHECK(c.json("GET", "/api/estop", "guest-token")["estopped"] == true);  // a broadcast never overrides the local e-stop

  // The origin's own e-stop is local too: it acknowledges its share and still forwards to the others.
  a.json("POST", "/api/stop", "guest-token", "", &status);
  auto from_stopped = post(a, "/api/command", "user-token", R"({"instruction":"go"})", kBroadcast, &status);
  REQUIRE(status == 200);
  CHECK(node_named(from_stopped, "alpha")["executed"] == false);
  CHECK(node_named(from_stopped, "alpha")["reason"] == "estop_active");
  CHECK(node_named(from_stopped, "bravo")["http_status"] == 404);

  // Without a broadcast signal, /api/command is just the local chat endpoint.
  b.json("POST", "/api/command", "user-token", R"({"instruction":"hi"})", &status);
  CHECK(status == 404);
}

TEST_CASE("swarm: forwarded requests are never forwarded again, even by a node with a swarm of its own") {
  TempDir dir;
  // bravo has a swarm of its own (alpha-twin): if bravo re-forwarded what alpha forwarded, alpha-twin would stop.
  RcandProcess alpha_twin(swarm_robot_config("alpha-twin"));
  const auto b_file = dir.write("b-swarm.yaml", swarm_yaml({{"alpha-twin", "127.0.0.1", alpha_twin.port()}}));
  RcandProcess b(swarm_robot_config("bravo", b_file));
  const auto a_file = dir.write("a-swarm.yaml", swarm_yaml({{"bravo", "127.0.0.1", b.port()}}));
  RcandProcess a(swarm_robot_config("alpha", a_file));

  int status = 0;
  auto report = post(a, "/api/stop", "owner-token", R"({"broadcast":true})", {}, &status);
  REQUIRE(status == 200);
  CHECK(report["summary"]["total"] == 2);
  CHECK(report["summary"]["ok"] == 2);
  CHECK(count_events(b, "POST /api/stop") == 1);                  // bravo stopped ...
  CHECK(count_events(b, "swarm broadcast POST /api/stop") == 0);  // ... and forwarded nothing
  CHECK(count_events(alpha_twin, "POST /api/stop") == 0);
  CHECK(alpha_twin.json("GET", "/api/estop", "guest-token")["estopped"] == false);
  CHECK(count_events(a, "POST /api/stop") == 1);
  CHECK(count_events(a, "swarm broadcast POST /api/stop") == 1);

  // A request that carries both the broadcast signal and the forwarded mark is treated as forwarded.
  post(b, "/api/command", "user-token", R"({"instruction":"x","broadcast":true})",
       {{"X-Swarm-Broadcast", "true"}, {"X-Swarm-Forwarded", "rcan://someone"}}, &status);
  CHECK(status == 200);  // bravo is in e-stop: the acknowledgement, not a broadcast report
  CHECK(count_events(b, "swarm broadcast POST /api/command") == 0);
  CHECK(count_events(alpha_twin, "POST /api/command") == 0);
}

TEST_CASE("swarm: a broadcast needs the command's scope on the receiving node, and each peer checks its own") {
  TempDir dir;
  RcandProcess b(swarm_robot_config("bravo"));
  RcandProcess c(swarm_robot_config("charlie"));
  // alpha holds only a guest token for bravo: enough to stop it, not to command it.
  const auto swarm_file =
      dir.write("swarm.yaml",
                swarm_yaml({{"bravo", "127.0.0.1", b.port(), "guest-token"}, {"charlie", "127.0.0.1", c.port(), "user-token"}}));
  RcandProcess a(swarm_robot_config("alpha", swarm_file));
  int status = 0;

  // A guest may not command alpha: refused at alpha, nothing is forwarded.
  auto refused = post(a, "/api/command", "guest-token", R"({"instruction":"go"})", kBroadcast, &status);
  CHECK(status == 403);
  CHECK(refused["code"] == "INSUFFICIENT_PRIVILEGES");
  CHECK(count_events(a, "swarm broadcast POST /api/command") == 0);
  post(a, "/api/command", "", R"({"instruction":"go"})", kBroadcast, &status);
  CHECK(status == 401);

  // With control on alpha the broadcast goes out; bravo refuses alpha's guest token on its own.
  auto report = post(a, "/api/command", "user-token", R"({"instruction":"go"})", kBroadcast, &status);
  REQUIRE(status == 200);
  INFO(report.dump(2));
  const auto bravo = node_named(report, "bravo");
  CHECK(bravo["ok"] == false);
  CHECK(bravo["http_status"] == 403);
  CHECK(bravo["code"] == "INSUFFICIENT_PRIVILEGES");
  CHECK(node_named(report, "charlie")["http_status"] == 404);  // charlie accepted the token; it has no chat

  // The guest token still stops bravo (scope status).
  report = post(a, "/api/stop", "guest-token", "", kBroadcast, &status);
  REQUIRE(status == 200);
  CHECK(node_named(report, "bravo")["ok"] == true);
  CHECK(b.json("GET", "/api/estop", "guest-token")["estopped"] == true);

  // A forwarded command from a peer is checked like any other: a wrong token is 401 on that node.
  post(b, "/api/command", "not-a-token", R"({"instruction":"go"})", {{"X-Swarm-Forwarded", "rcan://x"}}, &status);
  CHECK(status == 401);
}

TEST_CASE("swarm: the body selects nodes by name or tag; an unknown name lists the known ones but never skips the local stop") {
  TempDir dir;
  RcandProcess b(swarm_robot_config("bravo"));
  RcandProcess c(swarm_robot_config("charlie"));
  const auto swarm_file = dir.write("swarm.yaml", swarm_yaml({{"bravo", "127.0.0.1", b.port(), "owner-token", {"rover"}},
                                                              {"charlie", "127.0.0.1", c.port(), "owner-token", {"arm"}}}));
  RcandProcess a(swarm_robot_config("alpha", swarm_file));
  int status = 0;
  auto report = post(a, "/api/stop", "owner-token", R"({"broadcast":true,"tags":["rover"]})", {}, &status);
  REQUIRE(status == 200);
  CHECK(report["summary"]["total"] == 2);
  CHECK(node_named(report, "bravo")["ok"] == true);
  CHECK(c.json("GET", "/api/estop", "guest-token")["estopped"] == false);

  b.json("POST", "/api/estop/clear", "owner-token", "", &status);
  a.json("POST", "/api/estop/clear", "owner-token", "", &status);
  auto unknown = post(a, "/api/stop", "owner-token", R"({"broadcast":true,"nodes":["delta"]})", {}, &status);
  CHECK(status == 400);
  CHECK(unknown["field"] == "nodes");
  CHECK(unknown["error"] == "unknown node 'delta'; known nodes: bravo, charlie");
  CHECK(a.json("GET", "/api/estop", "guest-token")["estopped"] == true);  // the local stop happened anyway
  CHECK(b.json("GET", "/api/estop", "guest-token")["estopped"] == false);

  auto wrong = post(a, "/api/command", "owner-token", R"({"broadcast":true,"nodes":[1]})", {}, &status);
  CHECK(status == 400);
  CHECK(wrong["field"] == "nodes");
}

TEST_CASE("swarm: a malformed swarm file stops a start and fails --check-config, naming the line; a reload to one is refused") {
  TempDir dir;
  const auto swarm_file = dir.write("swarm.yaml", "nodes:\n  - name: a\n    host: h\n");
  const auto config_file = dir.write("robot.rcan.yaml", swarm_robot_config("alpha", swarm_file).dump(2));
  dir.write("jwt.secret", kJwtSecret);
  const std::string missing_token = swarm_file.string() + ":2:5: error: nodes[0].token: missing";
  for (const bool check_only : {false, true}) {
    auto result = run_tool(rcand_binary(), {check_only ? "--check-config" : "--config", config_file.string(), "--plugin-path",
                                            plugin_dir().string(), "--port", "0"});
    CHECK(result.exit_code != 0);
    CHECK_MESSAGE(result.err.find(missing_token) != std::string::npos, result.err);
  }

  // Serving on a good file, a SIGHUP to a malformed one changes nothing; back to a good one, its peers are in force.
  RcandProcess bravo(swarm_robot_config("bravo"));
  dir.write("swarm.yaml", swarm_yaml({{"bravo", "127.0.0.1", bravo.port(), "owner-token"}}));
  RcandProcess alpha(swarm_robot_config("alpha", swarm_file));
  auto names = [&] {
    std::vector<std::string> seen;
    const json table = alpha.json("GET", "/api/swarm", "guest-token");
    INFO(table.dump());
    for (const auto& row : table["nodes"]) seen.push_back(row["name"]);
    return seen;
  };
  CHECK(names() == std::vector<std::string>{"bravo"});
  auto reload = [&](const std::string& expect) {
    REQUIRE(::kill(alpha.pid(), SIGHUP) == 0);
    return eventually([&] { return alpha.stderr_text().find(expect) != std::string::npos; });
  };
  dir.write("swarm.yaml", "nodes:\n  - name: a\n    host: h\n");
  CHECK(reload(missing_token));
  CHECK(names() == std::vector<std::string>{"bravo"});
  dir.write("swarm.yaml", swarm_yaml({{"charlie", "127.0.0.1", bravo.port(), "owner-token"}}));
  CHECK(reload(": applied: "));
  CHECK(names() == std::vector<std::string>{"charlie"});
}

TEST_CASE("rcanctl swarm status|stop|command: table or JSON per node, exit codes 0/1/2, clear config errors") {
  TempDir dir;
  RcandProcess b(swarm_robot_config("bravo"));
  RcandProcess c(swarm_robot_config("charlie"));
  const auto refused = refused_port();
  const auto good = dir.write("good.yaml", swarm_yaml({{"bravo", "127.0.0.1", b.port(), "owner-token", {"rover"}},
                                                       {"charlie", "localhost", c.port(), "user-token", {"rover", "arm"}}}));
  const auto partial =
      dir.write("partial.yaml", swarm_yaml({{"bravo", "127.0.0.1", b.port(), "owner-token"},
                                            {"ghost", "no-such-robot.invalid", refused, "owner-token", {}, "127.0.0.1"}}));
  const auto ctl = rcanctl_binary();

  auto table = run_tool(ctl, {"swarm", "status", "--swarm", good.string()});
  CHECK(table.exit_code == 0);
  INFO(table.out << table.err);
  CHECK(table.out.find("NAME") == 0);
  for (const char* column : {"ADDRESS", "REACHABLE", "STATE", "E-STOP", "CAPS", "LATENCY"})
    CHECK(table.out.find(column) != std::string::npos);
  CHECK(table.out.find("bravo ") != std::string::npos);
  CHECK(table.out.find("status,teleop,com.acme.gripper") != std::string::npos);
  CHECK(table.out.find("owner-token") == std::string::npos);  // tokens are never printed
  CHECK(table.out.find("user-token") == std::string::npos);
  // Aligned: the ADDRESS column starts at the same offset on every line.
  const auto header_offset = table.out.find("ADDRESS");
  const auto second_line = table.out.find('\n') + 1;
  CHECK(table.out.substr(second_line + header_offset, 10) == "127.0.0.1:");

  auto by_json = run_tool(ctl, {"swarm", "status", "--swarm", good.string(), "--json", "--tag", "arm"});
  CHECK(by_json.exit_code == 0);
  auto line = json::parse(by_json.out.substr(0, by_json.out.find('\n')));
  CHECK(line["name"] == "charlie");
  CHECK(line["reachable"] == true);
  CHECK(line["state"] == "idle");
  CHECK(line["estopped"] == false);
  CHECK(line["caps"].size() == 3);
  CHECK(by_json.out.find('\n') == by_json.out.size() - 1);  // one object: one node selected

  auto part = run_tool(ctl, {"swarm", "status", "--swarm", partial.string(), "--json"});
  CHECK(part.exit_code == 1);
  auto ghost = json::parse(part.out.substr(part.out.find('\n') + 1));
  CHECK(ghost["name"] == "ghost");
  CHECK(ghost["reachable"] == false);
  CHECK(ghost["address"] == "127.0.0.1:" + std::to_string(refused));  // the ip fallback was used

  auto stop = run_tool(ctl, with_stop_timeout({"swarm", "stop", "--swarm", good.string(), "--node", "bravo"}));
  CHECK(stop.exit_code == 0);
  CHECK(stop.out.find("motors stopped") != std::string::npos);
  CHECK(b.json("GET", "/api/estop", "guest-token")["estopped"] == true);
  CHECK(c.json("GET", "/api/estop", "guest-token")["estopped"] == false);

  auto command = run_tool(ctl, {"swarm", "command", "--swarm", good.string(), "--instruction", "go forward", "--json"});
  CHECK(command.exit_code == 1);  // no chat anywhere: every node reports 404
  CHECK(command.out.find("CAPABILITY_NOT_FOUND") != std::string::npos);
  CHECK(command.out.find("estop_active") == std::string::npos);  // rcanctl's own requests are not forwarded ones

  // Usage and config errors: exit 2 with a clear message.
  auto missing = run_tool(ctl, {"swarm", "status", "--swarm", (dir.path() / "none.yaml").string()});
  CHECK(missing.exit_code == 2);
  CHECK(missing.err.find("none.yaml: error: cannot read the swarm file: No such file or directory") != std::string::npos);
  const auto bad = dir.write("bad.yaml", "nodes:\n  - name: a\n    host: h\n    token: t\n  - name: b\n    token: secret-b\n");
  auto malformed = run_tool(ctl, {"swarm", "status", "--swarm", bad.string()});
  CHECK(malformed.exit_code == 2);
  CHECK(malformed.err.find("bad.yaml:5:5: error: nodes[1].host: missing") != std::string::npos);
  CHECK(malformed.err.find("secret-b") == std::string::npos);
  auto unknown = run_tool(ctl, {"swarm", "stop", "--swarm", good.string(), "--node", "delta"});
  CHECK(unknown.exit_code == 2);
  CHECK(unknown.err.find("unknown node 'delta'; known nodes: bravo, charlie") != std::string::npos);
  CHECK(run_tool(ctl, {"swarm", "command", "--swarm", good.string()}).exit_code == 2);  // --instruction missing
  CHECK(run_tool(ctl, {"swarm", "dance"}).exit_code == 2);
}

TEST_CASE("rcanctl status|stop|command against one robot") {
  RcandProcess robot(swarm_robot_config("solo"));
  const auto ctl = rcanctl_binary();
  const std::string port = std::to_string(robot.port());
  auto status = run_tool(ctl, {"status", "--port", port, "--token", "guest-token", "--json"});
  CHECK(status.exit_code == 0);
  auto doc = json::parse(status.out);
  CHECK(doc["state"] == "idle");
  CHECK(doc["ruri"].get<std::string>().rfind("rcan://", 0) == 0);
  CHECK(run_tool(ctl, {"status", "--port", port, "--token", "wrong"}).exit_code == 1);
  CHECK(run_tool(ctl, {"status", "--port", port}).exit_code == 2);  // no token

  auto command = run_tool(ctl, {"command", "--port", port, "--token", "user-token", "--instruction", "hello"});
  CHECK(command.exit_code == 1);
  CHECK(command.out.find("CAPABILITY_NOT_FOUND") != std::string::npos);

  auto stop = run_tool(ctl, with_stop_timeout({"stop", "--port", port, "--token", "guest-token"}));
  CHECK(stop.exit_code == 0);
  CHECK(stop.out.find("motors stopped") != std::string::npos);
  CHECK(robot.json("GET", "/api/estop", "guest-token")["estopped"] == true);
}

TEST_CASE("swarm: robots at their own addresses (network namespaces, or loopback where the machine does not allow them)") {
  NetnsLab lab(2);
  std::vector<std::unique_ptr<RcandProcess>> peers;
  std::vector<std::string> addresses;
  for (int i = 1; i <= 2; ++i) {
    auto config = swarm_robot_config(i == 1 ? "bravo" : "charlie");
    if (lab.available()) {
      config["runtime"]["listen"]["address"] = lab.address(i);
      peers.push_back(std::make_unique<RcandProcess>(config, lab.launcher(i), lab.address(i)));
    } else {
      peers.push_back(std::make_unique<RcandProcess>(config));
    }
    addresses.push_back(peers.back()->host());
  }
  if (lab.available()) MESSAGE("network namespaces: bravo at " << addresses[0] << ", charlie at " << addresses[1]);
  else MESSAGE("network namespaces unavailable (" << lab.why_not() << "): this case runs on loopback");

  // bravo's mDNS name does not resolve here: its static ip is the fallback (§15.2).
  TempDir dir;
  const auto swarm_file = dir.write(
      "swarm.yaml", swarm_yaml({{"bravo", "bravo.rcand-test.invalid", peers[0]->port(), "owner-token", {"rover"}, addresses[0]},
                                {"charlie", addresses[1], peers[1]->port(), "owner-token", {"rover"}}}));
  RcandProcess a(swarm_robot_config("alpha", swarm_file));
  int status = 0;
  for (const auto& peer : peers) {
    peer->json("POST", "/api/action", "user-token", kSwarmMove, &status);
    REQUIRE(status == 200);
  }
  auto report = post(a, "/api/stop", "owner-token", "", kBroadcast, &status);
  REQUIRE(status == 200);
  INFO(report.dump(2));
  CHECK(report["summary"] == json{{"total", 3}, {"ok", 3}, {"failed", 0}});
  CHECK(node_named(report, "bravo")["address"] == addresses[0] + ":" + std::to_string(peers[0]->port()));
  for (const auto& peer : peers) {
    CHECK(drive_status(*peer)["moving"] == false);
    CHECK(peer->json("GET", "/api/estop", "guest-token")["estopped"] == true);
  }

  auto ctl = run_tool(rcanctl_binary(), {"swarm", "status", "--swarm", swarm_file.string(), "--tag", "rover"});
  CHECK(ctl.exit_code == 0);
  CHECK(ctl.out.find(addresses[1] + ":" + std::to_string(peers[1]->port())) != std::string::npos);
  CHECK(ctl.out.find("estop") != std::string::npos);
}
