// docs/protocol.md §3/§4 against a running rcand: every auth failure, with the exact status and body.
#include <doctest/doctest.h>

#include <algorithm>
#include <functional>

#include "libs/rcan/crypto.hpp"
#include "libs/rcan/jwt.hpp"
#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

void check_error_body(const json& body, int status, const std::string& code) {
  REQUIRE(body.is_object());
  CHECK(body["status"] == status);
  CHECK(body["code"] == code);
  CHECK(body["error"].is_string());
  CHECK_FALSE(body["error"].get<std::string>().empty());
}

std::string jwt_with(const std::function<void(rcand::JwtClaims&)>& edit, const std::string& secret = kJwtSecret) {
  rcand::JwtClaims claims;
  claims.sub = "tester";
  claims.iss = "test";
  claims.role = "owner";
  claims.aud = {"rcan://*"};
  claims.scope = {"status", "control", "config"};
  claims.iat = std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  claims.exp = claims.iat + 600;
  edit(claims);
  return rcand::issue_jwt_hs256(claims, secret);
}

}  // namespace

TEST_CASE("auth: public endpoints need no token; everything else is denied by default") {
  RcandProcess rcand(sim_config());
  int status = 0;
  auto health = rcand.json("GET", "/health", "", "", &status);
  CHECK(status == 200);
  CHECK(health["status"] == "ok");
  CHECK(health.contains("uptime_s"));
  CHECK(health.contains("version"));
  rcand.json("GET", "/api/discovery", "", "", &status);
  CHECK(status == 200);

  for (const auto& entry : std::vector<std::pair<std::string, std::string>>{{"GET", "/api/status"},
                                                                              {"POST", "/api/stop"},
                                                                              {"GET", "/api/estop"},
                                                                              {"POST", "/api/estop/clear"},
                                                                              {"GET", "/api/audit"},
                                                                              {"POST", "/api/action"},
                                                                              {"GET", "/api/cap/com.acme.gripper/state"},
                                                                              {"POST", "/api/nav/waypoint"}}) {
    // Named references, not structured bindings: CAPTURE makes a lambda, and clang 14 cannot capture a binding.
    const auto& method = std::get<0>(entry); const auto& path = std::get<1>(entry);
    CAPTURE(path);
    auto body = rcand.json(method, path, "", R"({"type":"move","linear":1,"angular":0})", &status);
    CHECK(status == 401);
    check_error_body(body, 401, "UNAUTHORIZED");
  }
  // The e-stop was not triggered by the unauthenticated stop.
  CHECK(rcand.json("GET", "/api/estop", "owner-token")["estopped"] == false);
}

TEST_CASE("auth: each JWT failure is a 401 with a clear message, never echoing the token") {
  RcandProcess rcand(sim_config());
  const auto now = std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  const std::string good = jwt_with([](auto&) {});
  int status = 0;
  rcand.json("GET", "/api/status", good, "", &status);
  REQUIRE(status == 200);

  std::string tampered = good;
  tampered.back() = tampered.back() == 'A' ? 'B' : 'A';
  const std::string wrong_key = jwt_with([](auto&) {}, "some-other-secret");
  const std::string expired = jwt_with([&](auto& c) {
    c.iat = now - 7200;
    c.exp = now - 3600;
  });
  const std::string future = jwt_with([&](auto& c) { c.iat = now + 3600; });
  const std::string wrong_aud = jwt_with([](auto& c) { c.aud = {"rcan://other.robot.deadbeef"}; });
  // alg none: header {"alg":"none","typ":"JWT"} with the good payload and no signature.
  const auto payload = good.substr(good.find('.') + 1, good.rfind('.') - good.find('.') - 1);
  const std::string alg_none = rcand::base64url_encode(R"({"alg":"none","typ":"JWT"})") + "." + payload + ".";
  const std::string alg_none_signed =
      rcand::base64url_encode(R"({"alg":"none","typ":"JWT"})") + "." + payload + "." + good.substr(good.rfind('.') + 1);

  for (const auto& entry : std::vector<std::pair<std::string, std::string>>{{"bad signature", tampered},
                                                                             {"wrong key", wrong_key},
                                                                             {"expired", expired},
                                                                             {"iat in the future", future},
                                                                             {"wrong aud", wrong_aud},
                                                                             {"alg none", alg_none},
                                                                             {"alg none with a signature", alg_none_signed},
                                                                             {"garbage", "not-a-token"},
                                                                             {"empty parts", ".."}}) {
    // Named references, not structured bindings: CAPTURE makes a lambda, and clang 14 cannot capture a binding.
    const auto& name = std::get<0>(entry); const auto& token = std::get<1>(entry);
    CAPTURE(name);
    const auto response = rcand.request("GET", "/api/status", token);
    CHECK(response.status == 401);
    const auto body = json::parse(response.body);
    check_error_body(body, 401, "UNAUTHORIZED");
    CHECK(response.body.find(token.substr(0, 20)) == std::string::npos);
  }
  // Secrets never reach the logs either.
  CHECK(rcand.stderr_text().find(kJwtSecret) == std::string::npos);
  CHECK(rcand.stderr_text().find(good.substr(good.rfind('.') + 1)) == std::string::npos);
}

TEST_CASE("auth: insufficient scope is 403 INSUFFICIENT_PRIVILEGES, on every scoped endpoint") {
  RcandProcess rcand(sim_config());
  int status = 0;
  const std::string guest_jwt = jwt_for("guest");
  for (const auto& guest : {std::string("guest-token"), guest_jwt}) {
    auto body = rcand.json("POST", "/api/action", guest, R"({"type":"move","linear":0.2,"angular":0})", &status);
    CHECK(status == 403);
    check_error_body(body, 403, "INSUFFICIENT_PRIVILEGES");
    rcand.json("GET", "/api/cap/com.acme.gripper/state", guest, "", &status);
    CHECK(status == 403);  // custom capabilities need at least control (§9.4)
    rcand.json("GET", "/api/audit", guest, "", &status);
    CHECK(status == 403);
    rcand.json("GET", "/api/status", guest, "", &status);
    CHECK(status == 200);
  }
  // USER controls but cannot clear the e-stop or read the audit log (config scope).
  rcand.json("POST", "/api/action", "user-token", R"({"type":"stop"})", &status);
  CHECK(status == 200);
  rcand.json("POST", "/api/estop/clear", "user-token", "", &status);
  CHECK(status == 403);
  rcand.json("GET", "/api/audit", "user-token", "", &status);
  CHECK(status == 403);
  // A JWT whose role allows control but whose scope[] omits it is refused too.
  const auto narrowed = jwt_with([](auto& c) { c.scope = {"status"}; });
  rcand.json("POST", "/api/action", narrowed, R"({"type":"stop"})", &status);
  CHECK(status == 403);
  rcand.json("GET", "/api/estop", "owner-token", "", &status);
  CHECK(status == 200);
}

TEST_CASE("auth: open mode only on loopback") {
  auto config = sim_config();
  config["runtime"]["auth"] = {{"mode", "open"}};
  SUBCASE("refused off loopback") {
    config["runtime"]["listen"]["address"] = "0.0.0.0";
    TempDir dir;
    const auto file = dir.write("robot.rcan.yaml", config.dump());
    auto result = run_tool(rcand_binary(), {"--config", file.string(), "--port", "0", "--plugin-path", plugin_dir().string()});
    CHECK(result.exit_code == 1);
    CHECK(result.err.find("loopback") != std::string::npos);
  }
  SUBCASE("served without tokens on loopback") {
    RcandProcess rcand(config);
    int status = 0;
    rcand.json("POST", "/api/action", "", R"({"type":"stop"})", &status);
    CHECK(status == 200);
  }
}

TEST_CASE("rcanctl token issue mints a JWT the robot accepts") {
  TempDir dir;
  const auto secret = dir.write("secret", std::string(kJwtSecret) + "\n");
  auto issued = run_tool(rcanctl_binary(), {"token", "issue", "--secret-file", secret.string(), "--role", "owner", "--ttl", "1h"});
  REQUIRE(issued.exit_code == 0);
  std::string token = issued.out;
  while (!token.empty() && (token.back() == '\n' || token.back() == '\r')) token.pop_back();
  CHECK(std::count(token.begin(), token.end(), '.') == 2);
  CHECK(token.find('\n') == std::string::npos);  // the JWT alone on stdout
  RcandProcess rcand(sim_config());
  int status = 0;
  rcand.json("POST", "/api/estop/clear", token, "", &status);
  CHECK(status == 200);
}
