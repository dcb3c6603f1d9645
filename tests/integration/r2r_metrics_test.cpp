// R2R messages in GET /metrics (issue 18): rcand_r2r_messages_total counts each message accepted from a transport and
// each one a transport took, by type and transport, on a real rcand with a WebSocket peer.
#include <doctest/doctest.h>

#include <optional>
#include <string>

#include "r2r_lab.hpp"
#include "rcand_process.hpp"
#include "ws_client.hpp"

using namespace rcand::test;
using nlohmann::json;

TEST_CASE("r2r metrics: a peer's status counts as received over ws; the robot's own status as sent") {
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  RcandProcess robot(r2r_robot_config("alpha", token));
  WsClient peer;
  REQUIRE(peer.connect(robot.port(), "user-token") == 101);
  peer.send(r2r_message("probe", "status", {{"battery", 50}, {"state", "idle"}}));
  REQUIRE(poll_until<json>([&]() -> std::optional<json> { return peer_status(robot, "probe"); }));

  // The robot's own status goes out every status_interval_ms (300 ms here): wait for one on the metrics page.
  const auto page = poll_until<std::string>([&]() -> std::optional<std::string> {
    auto text = robot.request("GET", "/metrics", "guest-token").body;
    if (text.find("rcand_r2r_messages_total{direction=\"sent\",type=\"status\",transport=\"ws\"}") == std::string::npos)
      return std::nullopt;
    return text;
  });
  REQUIRE(page);
  CHECK(page->find("\nrcand_r2r_messages_total{direction=\"received\",type=\"status\",transport=\"ws\"} 1\n") !=
        std::string::npos);
  CHECK(page->find("# TYPE rcand_r2r_messages_total counter\n") != std::string::npos);
}
