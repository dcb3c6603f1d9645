// Issue 28 item 12 on a real rcand: user text quoted back is cut to 200 bytes with controls (C0, C1) and bidi
// overrides replaced, on every path the issue names - a 405's path, /dashboard/<name>, /api/thoughts/<id>, the plugin
// reload's 404, the arm's unknown pose and joint - and an e-stop reason carrying U+202E reaches neither GET
// /api/estop, nor telemetry, nor the log with it. The hostile text arrives percent-encoded in paths (the HTTP parser
// refuses raw control bytes in a target) and as JSON strings in bodies.
#include <doctest/doctest.h>

#include <string>
#include <vector>

#include "rcand_process.hpp"
#include "ws_client.hpp"

using namespace rcand::test;
using namespace std::chrono_literals;
using nlohmann::json;

namespace {

// ESC [2J, CR LF (a forged log line), C1 CSI (U+009B), RIGHT-TO-LEFT OVERRIDE (U+202E), LEFT-TO-RIGHT ISOLATE (U+2066).
const std::string kHostile = "\x1b[2J\r\nforged\xc2\x9b\xe2\x80\xae\xe2\x81\xa6";
const std::string kHostileEncoded = "%1B%5B2J%0D%0Aforged%C2%9B%E2%80%AE%E2%81%A6";

json quoting_config() {
  auto config = sim_config();
  config["rcan_protocol"]["capabilities"] = {"status", "teleop", "chat", "arm", "com.acme.gripper"};
  config["agent"] = {{"provider", "grammar"}};
  config["physics"]["kinematics"] = json::array(
      {{{"joint", "shoulder"}, {"min_deg", -90}, {"max_deg", 90}}, {{"joint", "elbow"}, {"min_deg", 0}, {"max_deg", 135}}});
  config["drivers"].push_back({{"id", "arm0"}, {"protocol", "sim_arm"}});
  config["runtime"]["capabilities"]["arm"] = {{"poses", {{"ready", {{"shoulder", 30}}}}}};
  config["runtime"]["plugins"] = {{"allow_reload", true}};
  return config;
}

// The answer quotes the hostile text cut and made safe: small, no control or bidi character in any form.
void check_quoted(const std::string& what, const json& answer) {
  CAPTURE(what);
  const std::string text = answer.dump();
  CAPTURE(text.substr(0, 400));
  CHECK(text.size() < 1200);
  for (const std::string& forbidden : {std::string("\\u001b"), std::string("\\r"), std::string("\\n"), std::string("\xc2\x9b"),
                                       std::string("\\u009b"), std::string("\xe2\x80\xae"), std::string("\xe2\x81\xa6")})
    CHECK(text.find(forbidden) == std::string::npos);
  CHECK(text.find("?[2J??forged???") != std::string::npos);  // quoted, each unsafe character a '?'
}

}  // namespace

TEST_CASE("quoted text: 405, /dashboard/<name>, /api/thoughts/<id>, plugin reload 404 and the arm quote 200 safe bytes") {
  RcandProcess rcand(quoting_config());
  const std::string long_tail(6000, 'a');  // the path stays under the 16 KiB header limit
  int status = 0;

  auto answer = rcand.json("POST", "/dashboard/" + kHostileEncoded + long_tail, "owner-token", "{}", &status);
  CHECK(status == 405);
  check_quoted("405 on a path", answer);

  answer = rcand.json("GET", "/dashboard/" + kHostileEncoded + long_tail, {}, {}, &status);
  CHECK(status == 404);
  check_quoted("/dashboard/<name>", answer);

  answer = rcand.json("GET", "/api/thoughts/" + kHostileEncoded + long_tail, "owner-token", {}, &status);
  CHECK(status == 404);
  check_quoted("/api/thoughts/<id>", answer);

  answer = rcand.json("POST", "/api/plugins/" + kHostileEncoded + long_tail + "/reload", "owner-token", "{}", &status);
  CHECK(status == 404);
  check_quoted("plugin reload 404", answer);
  CHECK(rcand.json("GET", "/api/estop", "guest-token")["estopped"] == false);  // an unknown plugin stops nothing

  const std::string mebibyte = kHostile + std::string((1 << 20) - 256, 'a');
  answer = rcand.json("POST", "/api/action", "user-token", json{{"type", "arm_pose"}, {"pose", mebibyte}}.dump(), &status);
  CHECK(status == 400);
  check_quoted("arm: unknown pose", answer);
  answer =
      rcand.json("POST", "/api/action", "user-token", json{{"type", "arm_pose"}, {"joints", {{mebibyte, 10}}}}.dump(), &status);
  CHECK(status == 400);
  check_quoted("arm: unknown joint", answer);
}

TEST_CASE("quoted text: an e-stop reason with controls and U+202E is made safe for /api/estop, telemetry and the log") {
  RcandProcess rcand(sim_config());
  WsClient telemetry;
  REQUIRE(telemetry.connect(rcand.port(), "guest-token", "/ws/telemetry") == 101);
  int status = 0;
  rcand.json("POST", "/api/stop", "guest-token", json{{"reason", "halt " + kHostile + " now"}}.dump(), &status);
  REQUIRE(status == 200);
  const std::string safe = "halt ?[2J??forged??? now";
  CHECK(rcand.json("GET", "/api/estop", "guest-token")["reason"] == safe);
  json frame;
  for (int i = 0; i < 50 && !(frame.is_object() && frame["estop"].is_object()); ++i) {
    const auto text = telemetry.read(5s);
    REQUIRE(text);
    frame = json::parse(*text, nullptr, false);
  }
  REQUIRE(frame["estop"].is_object());
  CHECK(frame["estop"]["reason"] == safe);
  const std::string log = rcand.stderr_text();
  CHECK(log.find(safe) != std::string::npos);
  CHECK(log.find("\xe2\x80\xae") == std::string::npos);
  CHECK(log.find("\nforged") == std::string::npos);  // no forged log line
}
