// One rcand per robot (issue 28 item 1): a second rcand started on a robot that already runs one - same config and
// state dir, or the same port, or the same audit file - is refused before it creates a single driver: no device
// opened, no actuator halted, nothing written. A fixture driver (tests/plugins/driver.cpp, witness_file) appends a
// line to a file each time an instance is constructed or halted, so what the second process did to the robot's
// hardware is seen from outside it.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

std::string claim_read(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The sim robot plus the witness driver, its state dir, audit file and witness file in `shared`.
json witnessed_robot(const TempDir& shared) {
  auto config = sim_config();
  config["drivers"].push_back({{"id", "witness0"},
                               {"protocol", "org.rcand.test.fake_drive"},
                               {"witness_file", (shared.path() / "witness.log").string()}});
  config["runtime"]["state_dir"] = (shared.path() / "state").string();
  config["runtime"]["audit_file"] = (shared.path() / "audit.jsonl").string();
  return config;
}

std::vector<std::string> plugin_args(const std::filesystem::path& config_file, const std::string& port) {
  return {"--config",      config_file.string(),  "--port",        port,
          "--plugin-path", plugin_dir().string(), "--plugin-path", test_plugin_dir().string()};
}

// What a refused second rcand must not have done: construct (or halt) a driver, or write to the robot's files.
void check_touched_nothing(const ProcessResult& second, const TempDir& shared, const std::string& witness_before,
                           const std::string& audit_before) {
  CHECK(second.exit_code == 1);
  CHECK(claim_read(shared.path() / "witness.log") == witness_before);  // no driver constructed, none halted
  CHECK(second.err.find("actuators halted") == std::string::npos);     // no e-stop on its way out: it had nothing to stop
  CHECK(second.err.find("e-stop latched") == std::string::npos);
  CHECK(claim_read(shared.path() / "audit.jsonl") == audit_before);
}

}  // namespace

TEST_CASE("a second rcand on the same robot is refused before any driver exists, naming the rcand that runs it") {
  TempDir shared;
  const auto config = witnessed_robot(shared);
  RcandProcess first(config, {plugin_dir(), test_plugin_dir()});
  const std::string witness = claim_read(shared.path() / "witness.log");
  REQUIRE(witness == "constructed by pid " + std::to_string(first.pid()) + "\n");
  const std::string audit = claim_read(shared.path() / "audit.jsonl");

  SUBCASE("the same config file, so the same state dir") {
    const auto second = run_tool(rcand_binary(), plugin_args(first.dir().path() / "robot.rcan.yaml", "0"));
    check_touched_nothing(second, shared, witness, audit);
    CHECK(second.err.find("runtime.state_dir") != std::string::npos);
    CHECK(second.err.find("in use by another rcand (pid " + std::to_string(first.pid()) + ",") != std::string::npos);
  }
  SUBCASE("another state dir, the same port") {
    auto other = config;
    other["runtime"]["state_dir"] = (shared.path() / "other-state").string();
    other["runtime"]["audit_file"] = (shared.path() / "other-audit.jsonl").string();
    const auto file = shared.write("other.rcan.yaml", other.dump());
    shared.write("jwt.secret", kJwtSecret);
    const auto second = run_tool(rcand_binary(), plugin_args(file, std::to_string(first.port())));
    check_touched_nothing(second, shared, witness, audit);
    CHECK(second.err.find("cannot listen on 127.0.0.1:" + std::to_string(first.port())) != std::string::npos);
  }
  SUBCASE("another state dir and port, the same audit file") {
    auto other = config;
    other["runtime"]["state_dir"] = (shared.path() / "other-state").string();
    const auto file = shared.write("other.rcan.yaml", other.dump());
    shared.write("jwt.secret", kJwtSecret);
    const auto second = run_tool(rcand_binary(), plugin_args(file, "0"));
    check_touched_nothing(second, shared, witness, audit);
    CHECK(second.err.find("runtime.audit_file") != std::string::npos);
    CHECK(second.err.find("in use by another rcand") != std::string::npos);
  }
  // The first one never noticed: serving, unlatched, moving.
  CHECK(first.json("GET", "/api/estop", "guest-token")["estopped"] == false);
  int status = 0;
  first.json("POST", "/api/action", "user-token", R"({"type":"move","linear":0.2,"angular":0.0,"duration_ms":100})", &status);
  CHECK(status == 200);
}
