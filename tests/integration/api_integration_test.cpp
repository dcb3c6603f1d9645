// The HTTP API of docs/protocol.md §7 and §9 against a running rcand: discovery, status, capabilities and bad input.
#include <doctest/doctest.h>

#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;

TEST_CASE("discovery and status advertise the same capabilities as the config") {
  RcandProcess rcand(sim_config());
  auto discovery = rcand.json("GET", "/api/discovery");
  const json expected = {"status", "teleop", "com.acme.gripper"};
  CHECK(discovery["capabilities"] == expected);
  CHECK(discovery["txt_record"]["caps"] == "status,teleop,com.acme.gripper");
  CHECK(discovery["port"] == rcand.port());
  CHECK(discovery["ruri"] == "rcan://rcand.sim-rover.1a2b3c4d");
  CHECK(discovery["name"] == "test-rover");
  CHECK(discovery["version"] == "1.3.0");
  CHECK(discovery["service_type"] == "_rcan._tcp");
  CHECK(discovery["status"] == "idle");

  auto status = rcand.json("GET", "/api/status", "guest-token");
  CHECK(status["caps"] == expected);
  CHECK(status["rcan_version"] == "1.3.0");
  CHECK(status["ruri"] == discovery["ruri"]);
  CHECK(status["state"] == "idle");
  CHECK(status["estopped"] == false);
  CHECK(status["nav_running"] == false);
  for (auto key : {"name", "version", "uptime_s", "plugins", "drivers"}) CHECK(status.contains(key));
  CHECK(status["drivers"].size() == 2);
  // Secrets never reach /api/status.
  CHECK(status.dump().find("sha256") == std::string::npos);
  CHECK(status.dump().find(kJwtSecret) == std::string::npos);
}

TEST_CASE("auto-detected capabilities when rcan_protocol.capabilities is omitted") {
  auto config = sim_config();
  config["rcan_protocol"].erase("capabilities");
  RcandProcess rcand(config);
  // The sim drive implements differential_drive: teleop, and nav because sim_config() has the §10.2 physics.
  CHECK(rcand.json("GET", "/api/discovery")["capabilities"] == json{"status", "nav", "teleop"});
}

TEST_CASE("an undeclared capability's endpoint is 404 CAPABILITY_NOT_FOUND and reaches no plugin") {
  auto config = sim_config();
  config["rcan_protocol"]["capabilities"] = {"status", "com.acme.gripper"};  // no teleop
  RcandProcess rcand(config);
  int status = 0;
  for (const auto& entry : std::vector<std::tuple<std::string, std::string, std::string>>{
           {"POST", "/api/action", R"({"type":"move","linear":0.5,"angular":0})"},
           {"POST", "/api/action", R"({"type":"grip","state":"open"})"},
           {"POST", "/api/nav/waypoint", R"({"distance_m":1,"heading_deg":0})"},
           {"GET", "/api/nav/status", ""},
           {"POST", "/api/command", R"({"instruction":"go"})"},
           {"GET", "/api/stream/mjpeg", ""},
           {"GET", "/api/cap/org.example.thing/anything", ""}}) {
    // Named references, not structured bindings: CAPTURE makes a lambda, and clang 14 cannot capture a binding.
    const auto& method = std::get<0>(entry); const auto& path = std::get<1>(entry); const auto& body = std::get<2>(entry);
    CAPTURE(path);
    CAPTURE(body);
    auto answer = rcand.json(method, path, "owner-token", body, &status);
    CHECK(status == 404);
    CHECK(answer["code"] == "CAPABILITY_NOT_FOUND");
    CHECK(answer["status"] == 404);
  }
  auto drive = rcand.json("GET", "/api/drivers/drive0", "owner-token")["status"];
  CHECK(drive["commands"] == 0);
  CHECK(drive["timeline"].empty());
  // Undeclared but authenticated first: no token still gives 401, not a capability list.
  rcand.json("POST", "/api/nav/waypoint", "", "{}", &status);
  CHECK(status == 401);
}

TEST_CASE("teleop moves the simulated drive through the gate, with mixing; out of range is refused, not clamped") {
  RcandProcess rcand(sim_config());
  int status = 0;
  for (const char* body : {R"({"type":"move","linear":5,"angular":0,"duration_ms":2000})",
                           R"({"type":"move","linear":1e300,"angular":0,"duration_ms":2000})",
                           R"({"type":"move","linear":0.5,"angular":-7,"duration_ms":2000})"}) {
    CAPTURE(body);
    auto refused = rcand.json("POST", "/api/action", "user-token", body, &status);
    CHECK(status == 400);
    CHECK(refused["code"] == "BAD_REQUEST");
    CHECK((refused["field"] == "linear" || refused["field"] == "angular"));
  }
  CHECK(rcand.json("GET", "/api/drivers/drive0", "owner-token")["status"]["commands"] == 0);
  auto answer = rcand.json("POST", "/api/action", "user-token", R"({"type":"move","linear":1,"angular":0,"duration_ms":2000})", &status);
  REQUIRE(status == 200);
  CHECK(answer["linear"] == 1.0);
  auto drive = rcand.json("GET", "/api/drivers/drive0", "guest-token")["status"];
  CHECK(drive["left"] == doctest::Approx(1.0));
  CHECK(drive["right"] == doctest::Approx(1.0));
  rcand.json("POST", "/api/action", "user-token", R"({"type":"move","linear":0,"angular":0.5,"duration_ms":2000})", &status);
  drive = rcand.json("GET", "/api/drivers/drive0", "guest-token")["status"];
  CHECK(drive["left"] == doctest::Approx(-0.5));
  CHECK(drive["right"] == doctest::Approx(0.5));
  rcand.json("POST", "/api/action", "user-token", R"({"type":"stop"})", &status);
  CHECK(status == 200);
  CHECK(rcand.json("GET", "/api/drivers/drive0", "guest-token")["status"]["moving"] == false);
}

TEST_CASE("the vendor capability com.acme.gripper serves under /api/cap/ through the gate") {
  RcandProcess rcand(sim_config());
  int status = 0;
  auto closed = rcand.json("POST", "/api/cap/com.acme.gripper/grip", "user-token", R"({"state":"close"})", &status);
  CHECK(status == 200);
  auto state = rcand.json("GET", "/api/cap/com.acme.gripper/state", "user-token", "", &status);
  CHECK(status == 200);
  CHECK(state["opening"] == 0.0);
  rcand.json("POST", "/api/cap/com.acme.gripper/grip", "user-token", R"({"state":"sideways"})", &status);
  CHECK(status == 400);
  rcand.json("GET", "/api/cap/com.acme.gripper/nope", "user-token", "", &status);
  CHECK(status == 404);
}

TEST_CASE("bad input gets a clear error naming the field, and nothing moves") {
  RcandProcess rcand(sim_config());
  int status = 0;
  for (const auto& entry : std::vector<std::pair<std::string, std::string>>{
           {R"({"type":"move","linear":"fast","angular":0})", "linear"},
           {R"({"type":"move"})", "linear"},
           {R"({"type":"move","linear":0.5,"angular":null})", "angular"},
           {R"({"type":"move","linear":0.5,"angular":0,"duration_ms":-5})", "duration_ms"},
           {R"({"type":"move","linear":0.5,"angular":0,"duration_ms":"soon"})", "duration_ms"},
           {R"({"type":"dance"})", "type"},
           {R"({"linear":0.5})", "type"},
           {R"([1,2,3])", "type"},
           {R"({"type":"move",)", "body"}}) {
    // Named references, not structured bindings: CAPTURE makes a lambda, and clang 14 cannot capture a binding.
    const auto& body = std::get<0>(entry); const auto& field = std::get<1>(entry);
    CAPTURE(body);
    auto answer = rcand.json("POST", "/api/action", "user-token", body, &status);
    CHECK(status == 400);
    CHECK(answer["code"] == "BAD_REQUEST");
    CHECK(answer["field"] == field);
  }
  CHECK(rcand.json("GET", "/api/drivers/drive0", "guest-token")["status"]["commands"] == 0);

  // Nesting bombs and oversized bodies.
  rcand.json("POST", "/api/action", "user-token", std::string(5000, '['), &status);
  CHECK(status == 400);
  auto big = rcand.request("POST", "/api/action", "user-token", std::string(1024 * 1024 + 10, ' '));
  CHECK(big.status == 413);
  CHECK(json::parse(big.body)["code"] == "PAYLOAD_TOO_LARGE");

  auto missing = rcand.json("GET", "/api/nowhere", "user-token", "", &status);
  CHECK(status == 404);
  CHECK(missing["code"] == "NOT_FOUND");
  auto wrong_method = rcand.json("GET", "/api/stop", "user-token", "", &status);
  CHECK(status == 405);
  CHECK(wrong_method["allowed"] == json{"POST"});
  // Query parameters: the whole value must be a positive integer (no wrap-around of "-5", no "5abc" read as 5).
  for (const std::string limit : {"-5", "5abc", "0", "", "99999999999999999999999"}) {
    CAPTURE(limit);
    auto answer = rcand.json("GET", "/api/audit?limit=" + limit, "owner-token", "", &status);
    CHECK(status == 400);
    CHECK(answer["field"] == "limit");
  }
  CHECK(rcand.json("GET", "/api/audit?limit=2", "owner-token", "", &status)["entries"].size() <= 2);
  CHECK(status == 200);
  // Still serving after all of it.
  rcand.json("GET", "/api/status", "guest-token", "", &status);
  CHECK(status == 200);
}

TEST_CASE("a capability whose required actuator is not configured is out of service, and says why") {
  auto config = sim_config();
  config["drivers"] = json::array({{{"id", "gripper0"}, {"protocol", "acme_gripper_sim"}}});  // no drive
  RcandProcess rcand(config);
  int status = 0;
  auto answer = rcand.json("POST", "/api/action", "user-token", R"({"type":"stop"})", &status);
  CHECK(status == 503);
  CHECK(answer["code"] == "UNAVAILABLE");
  CHECK(answer["error"].get<std::string>().find("differential_drive") != std::string::npos);
  CHECK(rcand.json("GET", "/api/status", "guest-token")["capabilities"]["teleop"]["state"] == "failed");
  // The gripper still serves.
  rcand.json("GET", "/api/cap/com.acme.gripper/state", "user-token", "", &status);
  CHECK(status == 200);
}
