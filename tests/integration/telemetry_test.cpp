// WS /ws/telemetry and GET /metrics on a real rcand (issue 18): the upgrade refused without credentials, frames
// about 200 ms apart with every MUST field, an HTTP e-stop pushed to the client at once (not at the next tick), a
// client's {"cmd":"stop"} latching through POST /api/stop's row, bad messages answered without closing, a client
// that never reads dropped while another keeps its cadence, and /metrics passing `promtool check metrics`.
#include <doctest/doctest.h>

#include <sys/socket.h>

#include <chrono>
#include <future>
#include <iostream>
#include <thread>

#include "promtool.hpp"
#include "rcand_process.hpp"
#include "ws_client.hpp"

using namespace rcand::test;
using nlohmann::json;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

namespace {

constexpr const char* kPath = "/ws/telemetry";

// The next message of `type` (skipping others), or null when none came within `within`.
json next_of(WsClient& client, const std::string& type, std::chrono::milliseconds within = 5s) {
  const auto deadline = Clock::now() + within;
  while (Clock::now() < deadline) {
    const auto text = client.read(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()));
    if (!text) return nullptr;
    json message = json::parse(*text, nullptr, false);
    if (message.is_object() && message.value("type", "") == type) return message;
  }
  return nullptr;
}

double metric(const RcandProcess& robot, const std::string& line_prefix) {
  const auto page = robot.request("GET", "/metrics", "guest-token").body;
  const auto at = page.find("\n" + line_prefix + " ");
  if (at == std::string::npos) return -1;
  return std::stod(page.substr(at + line_prefix.size() + 2));
}

}  // namespace

TEST_CASE("telemetry: the upgrade needs a credential (401 before the upgrade); ?token= works like the header") {
  RcandProcess robot(sim_config());
  WsClient anonymous;
  CHECK(anonymous.connect(robot.port(), "", kPath) == 401);
  WsClient wrong;
  CHECK(wrong.connect(robot.port(), "not-a-token", kPath) == 401);
  WsClient by_query;
  REQUIRE(by_query.connect(robot.port(), "", std::string(kPath) + "?token=guest-token") == 101);
  CHECK(!next_of(by_query, "telemetry").is_null());
  // Another path is not this service's: the upgrade goes on to the route table (404).
  WsClient elsewhere;
  CHECK(elsewhere.connect(robot.port(), "guest-token", "/ws/nothing") == 404);
}

TEST_CASE("telemetry: frames about every 200 ms with every MUST field") {
  RcandProcess robot(sim_config());
  WsClient client;
  REQUIRE(client.connect(robot.port(), "guest-token", kPath) == 101);
  json first = next_of(client, "telemetry");
  REQUIRE(first.is_object());
  for (const char* key : {"ts", "loop_latency_ms", "loop_count", "paused", "estopped", "nav_running", "obstacles", "battery_v"})
    CHECK_MESSAGE(first.contains(key), key);
  CHECK(first["estopped"] == false);
  CHECK(first["paused"] == false);
  CHECK(first["capabilities"]["teleop"] == "ok");
  CHECK(first["drivers"]["drive0"] == "ok");
  auto last = Clock::now();
  auto last_seq = first["seq"].get<std::uint64_t>();
  for (int i = 0; i < 6; ++i) {
    const json frame = next_of(client, "telemetry", 2s);
    REQUIRE(frame.is_object());
    const auto now = Clock::now();
    const auto gap = std::chrono::duration_cast<std::chrono::milliseconds>(now - last).count();
    CHECK(gap >= 100);
    CHECK(gap <= 1000);
    CHECK(frame["seq"].get<std::uint64_t>() > last_seq);
    CHECK(frame["ts"].get<std::int64_t>() >= first["ts"].get<std::int64_t>());
    last = now;
    last_seq = frame["seq"].get<std::uint64_t>();
  }
}

TEST_CASE("telemetry: an HTTP e-stop is pushed at once, and so is the clear") {
  RcandProcess robot(sim_config());
  WsClient client;
  REQUIRE(client.connect(robot.port(), "guest-token", kPath) == 101);
  REQUIRE(next_of(client, "telemetry").is_object());
  const auto sent = Clock::now();
  REQUIRE(robot.request("POST", "/api/stop", "guest-token").status == 200);
  json pushed;
  while (true) {
    pushed = next_of(client, "telemetry", 2s);
    REQUIRE(pushed.is_object());
    if (pushed["estopped"] == true) break;
  }
  const auto took = std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - sent).count();
  CHECK(pushed["event"] == "estop_latched");  // a push, not the next tick
  CHECK(took < 500);
  CHECK(pushed["estop"]["source"] == "guest-principal");

  REQUIRE(robot.request("POST", "/api/estop/clear", "owner-token").status == 200);
  json cleared;
  do {
    cleared = next_of(client, "telemetry", 2s);
    REQUIRE(cleared.is_object());
  } while (cleared["estopped"] == true);
  CHECK(cleared["event"] == "estop_cleared");
  CHECK(metric(robot, "rcand_estop_latches_total") == 1);
}

TEST_CASE("telemetry: {\"cmd\":\"stop\"} latches through POST /api/stop's row; bad messages get an error, not a close") {
  RcandProcess robot(sim_config());
  WsClient client;
  REQUIRE(client.connect(robot.port(), "user-token", kPath) == 101);
  client.send("this is not json");
  json error = next_of(client, "error");
  REQUIRE(error.is_object());
  CHECK(error["code"] == "BAD_REQUEST");
  client.send(R"({"cmd":"dance"})");
  error = next_of(client, "error");
  REQUIRE(error.is_object());
  CHECK(error["code"] == "UNKNOWN_COMMAND");
  client.send(R"({"cmd":42})");
  CHECK(next_of(client, "error")["code"] == "BAD_REQUEST");
  CHECK(robot.json("GET", "/api/estop", "guest-token")["estopped"] == false);

  client.send(R"({"cmd":"stop","reason":"operator pressed the dashboard button"})");
  const json stopped = next_of(client, "stopped");
  REQUIRE(stopped.is_object());
  CHECK(stopped["estopped"] == true);
  CHECK(stopped["motors_stopped"] == true);
  const json estop = robot.json("GET", "/api/estop", "guest-token");
  CHECK(estop["estopped"] == true);
  CHECK(estop["source"] == "user-principal");
  CHECK(estop["reason"] == "operator pressed the dashboard button");
  // Who and from where, in words (issue 29 item 4): a client that names no "from" is "a telemetry client".
  CHECK(estop["principal"] == "user-principal");
  CHECK(estop["origin"] == "request");
  CHECK(estop["from"] == "a telemetry client (WebSocket)");
  CHECK(estop["summary"] ==
        "Stopped by user-principal from a telemetry client (WebSocket): operator pressed the dashboard button");
  // The same audit entry as an HTTP stop.
  const json audit = robot.json("GET", "/api/audit", "owner-token");
  bool audited = false;
  for (const auto& entry : audit["entries"])
    audited = audited || (entry.value("event", "") == "POST /api/stop" && entry.value("principal", "") == "user-principal");
  CHECK(audited);
  // Still connected: frames go on, now latched.
  CHECK(next_of(client, "telemetry")["estopped"] == true);
}

TEST_CASE("telemetry: a client that never reads is dropped; another keeps its 200 ms cadence") {
  RcandProcess robot(sim_config());
  WsClient stuck;
  // The smallest receive buffer the kernel allows, set before connecting: its backlog shows on rcand's side soon.
  stuck.ws.next_layer().socket().open(boost::asio::ip::tcp::v4());
  stuck.ws.next_layer().socket().set_option(boost::asio::socket_base::receive_buffer_size(1024));
  REQUIRE(stuck.connect(robot.port(), "guest-token", kPath) == 101);
  WsClient reader;
  REQUIRE(reader.connect(robot.port(), "guest-token", kPath) == 101);
  REQUIRE(next_of(reader, "telemetry").is_object());
  auto last = Clock::now();
  double dropped = 0;
  long worst_gap = 0;
  const auto deadline = Clock::now() + 60s;
  while (dropped < 1 && Clock::now() < deadline) {
    REQUIRE(next_of(reader, "telemetry", 2s).is_object());
    const auto now = Clock::now();
    worst_gap = std::max<long>(worst_gap, std::chrono::duration_cast<std::chrono::milliseconds>(now - last).count());
    last = now;
    dropped = metric(robot, "rcand_telemetry_clients_dropped_total{reason=\"slow\"}");
  }
  CHECK(dropped == 1);
  CHECK(worst_gap <= 1000);
  CHECK(metric(robot, "rcand_telemetry_clients") == 1);
  // The stuck client, reading at last, finds the frames buffered before the drop, then the end.
  boost::beast::error_code ended;
  for (int i = 0; i < 10000 && stuck.read(5s, &ended); ++i) {
  }
  CHECK(ended);
}

TEST_CASE("metrics: scope status on the robot's port, promtool-clean, unauthenticated only on the loopback port") {
  // A free port for runtime.telemetry.metrics_port: bound and released (the schema takes no 0).
  boost::asio::io_context io;
  boost::asio::ip::tcp::acceptor probe(io, {boost::asio::ip::make_address("127.0.0.1"), 0});
  const auto metrics_port = probe.local_endpoint().port();
  probe.close();
  json config = sim_config();
  config["runtime"]["telemetry"] = {{"metrics_port", metrics_port}};
  RcandProcess robot(config);
  CHECK(robot.request("GET", "/metrics").status == 401);
  robot.request("GET", "/api/status", "guest-token");
  robot.request("POST", "/api/stop", "guest-token");
  WsClient watcher;
  REQUIRE(watcher.connect(robot.port(), "guest-token", kPath) == 101);
  REQUIRE(next_of(watcher, "telemetry").is_object());

  const auto scrape = robot.request("GET", "/metrics", "guest-token");
  REQUIRE(scrape.status == 200);
  CHECK(scrape.headers.at("content-type").starts_with("text/plain; version=0.0.4"));
  const std::string& page = scrape.body;
  for (const char* line : {"rcand_estop_latches_total 1", "rcand_estop_latched 1", "rcand_telemetry_clients 1",
                           "rcand_estop_halt_latency_seconds_count 1", "rcand_driver_state{driver=\"drive0\",state=\"ok\"} 1",
                           "rcand_http_requests_total{method=\"GET\",route=\"/api/status\",code=\"200\"} 1",
                           "rcand_driver_halt_latency_seconds_count{driver=\"drive0\"} 1"})
    CHECK_MESSAGE(page.find(std::string("\n") + line + "\n") != std::string::npos, line);

  const auto local = rcand::http::request("127.0.0.1", metrics_port, "GET", "/metrics", "", {}, std::chrono::seconds(5));
  CHECK(local.status == 200);
  CHECK(local.body.find("rcand_telemetry_clients 1") != std::string::npos);
  CHECK(rcand::http::request("127.0.0.1", metrics_port, "GET", "/api/status", "", {}, std::chrono::seconds(5)).status == 404);

  rcand::test::check_promtool_clean(page);
}

TEST_CASE("rcanctl watch: JSON lines, refused credentials, connection loss") {
  RcandProcess robot(sim_config());
  const std::string port = std::to_string(robot.port());
  const auto watched = run_tool(rcanctl_binary(), {"watch", "--port", port, "--token", "guest-token", "--json", "--frames", "3"});
  CHECK(watched.exit_code == 0);
  CHECK(count_of(watched.out, "\"type\":\"telemetry\"") == 3);
  const auto lines = run_tool(rcanctl_binary(), {"watch", "--port", port, "--token", "guest-token", "--frames", "2"});
  INFO(lines.err);
  CHECK(lines.exit_code == 0);
  CHECK(count_of(lines.out, "estopped no") == 2);

  const auto refused = run_tool(rcanctl_binary(), {"watch", "--port", port, "--token", "wrong-token", "--frames", "1"});
  CHECK(refused.exit_code == 1);
  CHECK(refused.err.find("authentication failed (HTTP 401)") != std::string::npos);

  auto lost = std::async(std::launch::async, [&] {
    return run_tool(rcanctl_binary(), {"watch", "--port", port, "--token", "guest-token", "--json"});
  });
  // Once it shows up as a client, the robot goes away under it.
  for (auto deadline = Clock::now() + 10s; metric(robot, "rcand_telemetry_clients") < 1 && Clock::now() < deadline;)
    std::this_thread::sleep_for(20ms);
  robot.stop();
  const auto ended = lost.get();
  INFO(ended.err);
  CHECK(ended.exit_code == 1);
  CHECK(ended.err.find("connection to 127.0.0.1:" + port + " lost") != std::string::npos);
}
