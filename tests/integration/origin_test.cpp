// Issue 28 #2 over plain HTTP on a real rcand (the browser itself: dashboard/origin_browser_test.cpp): every request
// and WebSocket upgrade that carries an Origin other than the robot's own, or one in runtime.listen.allowed_origins,
// is refused with 403 ORIGIN_NOT_ALLOWED in every auth mode; so is a browser's request naming a host the robot does not
// know (DNS rebinding), and in auth mode open any request naming one (a rebinding page's GETs carry no Origin).
// Requests without Origin (curl, rcanctl, robots) are otherwise unaffected, and so is a body without a JSON content
// type.
#include <doctest/doctest.h>

#include <map>
#include <string>

#include "rcand_process.hpp"
#include "ws_client.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

using Headers = std::map<std::string, std::string>;

Headers upgrade_headers(Headers extra) {
  Headers headers{{"Connection", "Upgrade"},
                  {"Upgrade", "websocket"},
                  {"Sec-WebSocket-Version", "13"},
                  {"Sec-WebSocket-Key", "dGhlIHNhbXBsZSBub25jZQ=="}};
  headers.merge(extra);
  return headers;
}

void check_refused(const rcand::http::ClientResponse& answer, const std::string& why) {
  INFO(answer.body);
  CHECK(answer.status == 403);
  const json body = json::parse(answer.body, nullptr, false);
  CHECK(body.value("code", "") == "ORIGIN_NOT_ALLOWED");
  CHECK(body.value("status", 0) == 403);
  CHECK(body.value("error", "").find(why) != std::string::npos);
}

}  // namespace

TEST_CASE("origins: another origin is refused (403) on requests, the stop and the WebSocket upgrades, in every auth mode") {
  for (const bool open_mode : {true, false}) {
    CAPTURE(open_mode);
    auto config = sim_config();
    if (open_mode) config["runtime"]["auth"] = {{"mode", "open"}};
    RcandProcess robot(config);
    const std::string host = "127.0.0.1:" + std::to_string(robot.port());
    const Headers other{{"Origin", "http://127.0.0.1:1"}};
    check_refused(robot.request("POST", "/api/estop/clear", "owner-token", "{}", other), "another origin");
    check_refused(robot.request("POST", "/api/action", "owner-token", R"({"type":"move","linear":0.2})", other),
                  "another origin");
    check_refused(robot.request("GET", "/api/status", "owner-token", "", other), "another origin");
    check_refused(robot.request("POST", "/api/stop", "owner-token", "", other), "another origin");  // the stop lane too
    check_refused(robot.request("GET", "/ws/telemetry?token=owner-token", "", "", upgrade_headers(other)), "another origin");
    check_refused(robot.request("GET", "/api/status", "owner-token", "", {{"Origin", "null"}}), "origin 'null'");
    check_refused(
        robot.request("GET", "/api/status", "owner-token", "", {{"Origin", "http://localhost:" + std::to_string(robot.port())}}),
        "another origin");  // the Host says 127.0.0.1: another origin, even on the same machine
    CHECK(robot.json("GET", "/api/estop", "guest-token")["estopped"] == false);
    CHECK(drive_status(robot)["moving"] == false);
    CHECK(robot.stderr_text().find("403 (a page of http://127.0.0.1:1 (another origin") != std::string::npos);  // logged

    // The robot's own origin, and no Origin at all, are unaffected; a text/plain or form body is still read as JSON.
    const Headers own{{"Origin", "http://" + host}};
    CHECK(robot.request("GET", "/api/status", "owner-token", "", own).status == 200);
    CHECK(robot.request("POST", "/api/action", "owner-token", R"({"type":"stop"})", {{"Content-Type", "text/plain"}}).status ==
          200);
    CHECK(robot.request("POST", "/api/stop", "owner-token", "", own).status == 200);
    CHECK(robot.request("POST", "/api/estop/clear", "owner-token", "{}", own).status == 200);
    WsClient dashboard;  // the robot's own page's live link
    CHECK(dashboard.connect(robot.port(), "owner-token", "/ws/telemetry", "127.0.0.1", own) == 101);
    WsClient plain;  // no Origin, like rcanctl watch
    CHECK(plain.connect(robot.port(), "owner-token", "/ws/telemetry") == 101);
  }
}

TEST_CASE("origins: DNS rebinding is refused; names the robot knows and runtime.listen.allowed_origins are allowed") {
  auto config = sim_config();
  config["runtime"]["auth"] = {{"mode", "open"}};
  config["metadata"]["robot_name"] = "sim-rover";
  config["runtime"]["listen"]["allowed_origins"] = {"https://fleet.example.com", "http://rover-3.lan:8000"};
  RcandProcess robot(config);
  const std::string port = std::to_string(robot.port());
  // evil.example now resolves to 127.0.0.1: its page is same-origin with the robot by host and port.
  const Headers rebound{{"Host", "evil.example:" + port}, {"Origin", "http://evil.example:" + port}};
  check_refused(robot.request("POST", "/api/estop/clear", "", "{}", rebound), "'evil.example' is not a name of this robot");
  check_refused(robot.request("GET", "/ws/telemetry", "", "", upgrade_headers(rebound)), "not a name of this robot");
  // Its same-origin GET carries no Origin (nor, over plain HTTP, Sec-Fetch-Site), and in auth mode open needs no
  // credential: there every request's Host must name the robot.
  check_refused(robot.request("GET", "/api/status", "", "", {{"Host", "evil.example:" + port}}), "not a name of this robot");
  check_refused(
      robot.request("GET", "/api/status", "", "", {{"Host", "evil.example:" + port}, {"Sec-Fetch-Site", "same-origin"}}),
      "not a name of this robot");
  CHECK(robot.request("GET", "/api/status", "", "", {{"Host", "localhost:" + port}}).status == 200);  // curl localhost:PORT

  // The robot's names: localhost, its IP, metadata.robot_name.local; a listed name; a listed other origin.
  for (const std::string name : {"localhost", "127.0.0.1", "sim-rover.local"}) {
    CAPTURE(name);
    const Headers same{{"Host", name + ":" + port}, {"Origin", "http://" + name + ":" + port}};
    CHECK(robot.request("POST", "/api/estop/clear", "", "{}", same).status == 200);
  }
  CHECK(
      robot.request("GET", "/api/status", "", "", {{"Host", "rover-3.lan:8000"}, {"Origin", "http://rover-3.lan:8000"}}).status ==
      200);
  CHECK(robot.request("GET", "/api/status", "", "", {{"Origin", "https://fleet.example.com"}}).status == 200);
  WsClient fleet;
  CHECK(fleet.connect(robot.port(), "", "/ws/telemetry", "127.0.0.1", {{"Origin", "https://fleet.example.com"}}) == 101);
  check_refused(robot.request("GET", "/api/status", "", "", {{"Origin", "http://fleet.example.com"}}), "another origin");
}

TEST_CASE("origins: in tokens mode a request without browser marks is never refused for its Host") {
  RcandProcess robot(sim_config());
  const std::string port = std::to_string(robot.port());
  // curl (or a robot) reaching the robot by a name it does not know: its credential is what counts.
  CHECK(robot.request("GET", "/api/status", "guest-token", "", {{"Host", "rover-7.example:" + port}}).status == 200);
  // A browser's request by that name is another matter: a rebinding page's (with Origin) is refused.
  check_refused(robot.request("GET", "/api/status", "guest-token", "",
                              {{"Host", "rover-7.example:" + port}, {"Origin", "http://rover-7.example:" + port}}),
                "not a name of this robot");
}

TEST_CASE("origins: runtime.listen.allowed_origins refuses null, wildcards and anything that is not an origin") {
  for (const std::string bad : {"null", "*", "https://*.example.com", "fleet.example.com", "https://fleet.example.com/app"}) {
    CAPTURE(bad);
    auto config = sim_config();
    config["runtime"]["listen"]["allowed_origins"] = {bad};
    TempDir dir;
    const auto file = dir.write("robot.rcan.yaml", config.dump(2));
    const auto check = run_tool(rcand_binary(), {"--check-config", file.string(), "--plugin-path", plugin_dir().string()});
    INFO(check.out, check.err);
    CHECK(check.exit_code != 0);
    CHECK(check.err.find("runtime.listen.allowed_origins[0]") != std::string::npos);
  }
}
