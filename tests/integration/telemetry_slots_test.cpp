// Issue 28 #8 on a real rcand: WS /ws/telemetry's slots. One GUEST used to be able to take every socket (256) and lock
// the owner's dashboard out of its live link (no link: the pad does not drive). Now a principal below OWNER holds a
// few, the principals below OWNER on one address a few more, and the last slots are the OWNER's and CREATOR's; in auth
// mode open, where everyone is one principal, the per-address cap holds for everyone.
#include <doctest/doctest.h>

#include <memory>
#include <vector>

#include "eventually.hpp"
#include "rcand_process.hpp"
#include "ws_client.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

constexpr const char* kTelemetry = "/ws/telemetry";

// The upgrade as a plain HTTP request, to read a refusal's JSON body (WsClient only reports the status).
rcand::http::ClientResponse telemetry_upgrade(const RcandProcess& robot, const std::string& token) {
  return robot.request("GET", kTelemetry, token, "",
                       {{"Connection", "Upgrade"},
                        {"Upgrade", "websocket"},
                        {"Sec-WebSocket-Version", "13"},
                        {"Sec-WebSocket-Key", "dGhlIHNhbXBsZSBub25jZQ=="}});
}

struct Sockets {
  const RcandProcess& robot;
  std::vector<std::unique_ptr<WsClient>> held;
  int open(const std::string& token) {
    held.push_back(std::make_unique<WsClient>());
    return held.back()->connect(robot.port(), token, kTelemetry);
  }
  int open_many(const std::string& token, int tries) {
    int accepted = 0;
    for (int i = 0; i < tries; ++i) accepted += open(token) == 101 ? 1 : 0;
    return accepted;
  }
};

json refusal_body(const rcand::http::ClientResponse& answer) { return json::parse(answer.body, nullptr, false); }

}  // namespace

TEST_CASE("telemetry slots: a GUEST fills its own cap, not the robot's; the reserved slots stay the owner's") {
  auto config = sim_config();
  config["runtime"]["telemetry"] = {
      {"max_clients", 6}, {"reserved_clients", 2}, {"max_clients_per_principal", 3}, {"max_clients_per_address", 100}};
  RcandProcess robot(config);
  Sockets sockets{robot, {}};
  CHECK(sockets.open_many("guest-token", 6) == 3);  // was 6: and then the owner's dashboard got 503
  auto refused = telemetry_upgrade(robot, "guest-token");
  INFO(refused.body);
  CHECK(refused.status == 429);
  CHECK(refusal_body(refused).value("code", "") == "TOO_MANY_CONNECTIONS");
  CHECK(refusal_body(refused).value("error", "").find("runtime.telemetry.max_clients_per_principal") != std::string::npos);
  CHECK(refused.headers.contains("retry-after"));

  CHECK(sockets.open("user-token") == 101);  // 4 of 6: the last 2 are reserved
  refused = telemetry_upgrade(robot, "user-token");
  CHECK(refused.status == 503);
  CHECK(refusal_body(refused).value("code", "") == "SLOTS_RESERVED");

  WsClient& owner = *sockets.held.emplace_back(std::make_unique<WsClient>());
  REQUIRE(owner.connect(robot.port(), "owner-token", kTelemetry) == 101);  // the owner's live link
  CHECK(owner.read().has_value());
  CHECK(sockets.open("owner-token") == 101);
  CHECK(telemetry_upgrade(robot, "owner-token").status == 503);  // max_clients holds for everyone

  // A slot comes back when its socket closes (once rcand has read the close).
  sockets.held.front().reset();
  CHECK(eventually([&] { return sockets.open("owner-token") == 101; }));
}

TEST_CASE("telemetry slots: many principals on one address share its cap; OWNER is not counted against it") {
  auto config = sim_config();
  config["runtime"]["telemetry"] = {{"max_clients_per_principal", 3}, {"max_clients_per_address", 4}};
  RcandProcess robot(config);
  Sockets sockets{robot, {}};
  CHECK(sockets.open_many("guest-token", 3) == 3);
  CHECK(sockets.open("user-token") == 101);
  const auto refused = telemetry_upgrade(robot, "user-token");  // the user's own cap has room; the address's not
  INFO(refused.body);
  CHECK(refused.status == 429);
  CHECK(refusal_body(refused).value("error", "").find("address 127.0.0.1 already holds 4") != std::string::npos);
  CHECK(sockets.open(jwt_for("guest")) == 429);  // yet another principal (a JWT's subject): the same address
  CHECK(sockets.open_many("owner-token", 5) == 5);
}

TEST_CASE("telemetry slots: in auth mode open everyone is one principal, and the per-address cap still holds") {
  auto config = sim_config();
  config["runtime"]["auth"] = {{"mode", "open"}};
  config["runtime"]["telemetry"] = {{"max_clients_per_principal", 1}, {"max_clients_per_address", 3}};
  RcandProcess robot(config);
  Sockets sockets{robot, {}};
  CHECK(sockets.open_many("", 5) == 3);  // not 1 (the one principal's cap would be the robot's) and not 5
  CHECK(telemetry_upgrade(robot, "").status == 429);
}
