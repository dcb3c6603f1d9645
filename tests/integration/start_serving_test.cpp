// Serving before the capabilities are up (issue 32): rcand answers /health and the stop lane as soon as the kernel,
// the drivers and the latch record are ready; a capability whose start() has not returned answers 503 STARTING and
// shows "starting" in GET /api/status until it is up, then its routes answer. A restart after a crash is latched from
// the first request it serves, and a shutdown while a capability starts is clean. The capability is the fault drill
// fixture with its start() held on a FIFO until the test releases it.
#include <doctest/doctest.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <string>

#include "eventually.hpp"
#include "fault_drill.hpp"
#include "rcand_process.hpp"
#include "temp_dir.hpp"

using namespace rcand::test;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

const std::string kGated = "org.rcand.test.faulty";
const std::string kGatedOk = "/api/cap/" + kGated + "/ok";

// The fixture's start() blocked until release_gate(): a FIFO it reads one byte from.
struct Gate {
  TempDir dir{"rcand-start-gate"};
  std::filesystem::path fifo = dir.path() / "gate";
  Gate() { REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0); }
  void release() const {
    const int fd = ::open(fifo.c_str(), O_WRONLY | O_CLOEXEC);  // returns once the plugin has it open
    REQUIRE(fd >= 0);
    CHECK(::write(fd, "x", 1) == 1);
    ::close(fd);
  }
};

json gated_config(const Gate& gate, json config = sim_config()) {
  config["rcan_protocol"]["capabilities"].push_back(kGated);
  config["runtime"]["capabilities"][kGated] = {{"hook", "start"}, {"fault", "gate"}, {"gate", gate.fifo.string()}};
  config["runtime"]["plugin_start_timeout_ms"] = 120000;  // only the test (or a shutdown) ends the wait
  return config;
}

json gated_status(const RcandProcess& rcand) { return rcand.json("GET", "/api/status", "owner-token")["capabilities"][kGated]; }

json sim_with_state_dir(const json& state_dir) {
  auto config = sim_config();
  config["runtime"]["state_dir"] = state_dir;
  return config;
}

RcandProcess serving(const json& config) {
  return RcandProcess(config, {plugin_dir(), test_plugin_dir() / "faults"}, RcandProcess::Ready::Serving);
}

}  // namespace

TEST_CASE("rcand serves /health and the stop while a capability starts; the capability answers 503 STARTING until up") {
  Gate gate;
  RcandProcess rcand = serving(gated_config(gate));

  int status = 0;
  CHECK(rcand.json("GET", "/health", "", "", &status).value("status", "") == "ok");
  CHECK(status == 200);
  const auto starting = rcand.json("GET", kGatedOk, "owner-token", "", &status);
  CHECK(status == 503);
  CHECK(starting.value("code", "") == "STARTING");
  CHECK(starting.value("status", 0) == 503);
  CHECK(starting.value("capability", "") == kGated);
  CHECK(starting.contains("error"));
  CHECK(gated_status(rcand).value("state", "") == "starting");
  CHECK(gated_status(rcand)["routes"].empty());
  // Declared, so advertised (discovery and mDNS come from the one registry); the status says it is starting.
  const auto discovery = rcand.json("GET", "/api/discovery");
  CHECK(discovery.dump().find(kGated) != std::string::npos);

  drill::stop_within_limit(rcand, "stop-while-starting");
  CHECK(rcand.json("GET", "/api/estop", "guest-token").value("estopped", false));

  gate.release();
  CHECK(eventually([&] { return rcand.request("GET", kGatedOk, "owner-token").status == 200; }, 20s, 10ms));
  CHECK(rcand.json("GET", kGatedOk, "owner-token").value("ok", false));
  CHECK(gated_status(rcand).value("state", "") == "ok");  // read back at once: the status follows the route
  CHECK_FALSE(gated_status(rcand)["routes"].empty());
  // Its rows, installed once it was up, are counted like every other route's.
  const auto scrape = rcand.request("GET", "/metrics", "guest-token");
  REQUIRE(scrape.status == 200);
  CHECK_MESSAGE(
      scrape.body.find("rcand_http_requests_total{method=\"GET\",route=\"" + kGatedOk + "\",code=\"200\"}") != std::string::npos,
      scrape.body);
}

TEST_CASE("a restart after a crash is latched from the first request it serves, capabilities still starting") {
  TempDir shared("rcand-start-restart");
  Gate gate;
  auto config = gated_config(gate);
  config["runtime"]["state_dir"] = (shared.path() / "state").string();
  {
    RcandProcess first(sim_with_state_dir(config["runtime"]["state_dir"]));
    first.kill_hard();
  }
  RcandProcess rcand = serving(config);
  const auto estop = rcand.json("GET", "/api/estop", "guest-token");  // the first request it serves
  CHECK(estop.value("estopped", false));
  CHECK(estop.value("reason", "").find("without a clean shutdown") != std::string::npos);
  CHECK(gated_status(rcand).value("state", "") == "starting");
  int status = 0;
  rcand.json("POST", "/api/action", "user-token", R"({"type":"move","linear":0.2,"angular":0.0,"duration_ms":200})", &status);
  CHECK((status == 423 || status == 503));  // latched (teleop up) or starting: never a move
  gate.release();
}

TEST_CASE("a shutdown while a capability starts is clean: it does not wait out the start, and the next run is unlatched") {
  TempDir shared("rcand-start-shutdown");
  Gate gate;
  auto config = gated_config(gate);
  config["runtime"]["state_dir"] = (shared.path() / "state").string();
  {
    RcandProcess rcand = serving(config);
    CHECK(rcand.request("GET", "/health").status == 200);
    CHECK(gated_status(rcand).value("state", "") == "starting");
    // Exit 0: the shutdown finished (not the 5 s grace's exit 1, while the start would wait 120 s).
    const int exit_code = rcand.stop();
    CHECK_MESSAGE(exit_code == 0, rcand.stderr_text());
  }
  RcandProcess again(sim_with_state_dir(config["runtime"]["state_dir"]));
  CHECK_FALSE(again.json("GET", "/api/estop", "guest-token").value("estopped", true));
}
