// rcanctl's daily-work subcommands (issue 19) against a real rcand: the e-stop, moves (hold-to-move included), nav,
// plugins, the audit log, and `status` exiting 1 for a robot that reports a fault. Exit codes: 0 / 1 / 2.
#include <doctest/doctest.h>

#include <fstream>
#include <iterator>
#include <map>
#include <sstream>

#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

json operator_config() {
  auto config = sim_config();
  config["rcan_protocol"]["capabilities"] = {"status", "teleop", "nav", "com.acme.gripper"};
  return config;
}

struct Ctl {
  std::string port;
  ProcessResult operator()(std::vector<std::string> args, const std::string& token, const std::string& input = {}) const {
    args.insert(args.end(), {"--port", port, "--token", token});
    return run_tool(rcanctl_binary(), args, input);
  }
};

}  // namespace

TEST_CASE("rcanctl estop shows and clears the latch; clearing needs an owner") {
  RcandProcess rcand(operator_config());
  const Ctl ctl{std::to_string(rcand.port())};
  auto shown = ctl({"estop"}, "guest-token");
  CHECK(shown.exit_code == 0);
  CHECK(shown.out == "not latched\n");
  CHECK(ctl({"stop"}, "guest-token").exit_code == 0);
  shown = ctl({"estop", "show", "--json"}, "guest-token");
  CHECK(shown.exit_code == 0);
  CHECK(json::parse(shown.out)["estopped"] == true);
  CHECK(ctl({"estop"}, "guest-token").out.rfind("LATCHED since ", 0) == 0);

  const auto refused = ctl({"estop", "clear"}, "user-token");
  CHECK(refused.exit_code == 1);
  CHECK(refused.err.find("INSUFFICIENT_PRIVILEGES") != std::string::npos);
  CHECK(rcand.json("GET", "/api/estop", "guest-token")["estopped"] == true);
  const auto cleared = ctl({"estop", "clear"}, "owner-token");
  CHECK(cleared.exit_code == 0);
  CHECK(cleared.out == "e-stop cleared\n");
  CHECK(rcand.json("GET", "/api/estop", "guest-token")["estopped"] == false);
  CHECK(ctl({"estop", "sideways"}, "owner-token").exit_code == 2);
}

TEST_CASE("rcanctl move drives through teleop, refuses out-of-range input, and --hold stops on release") {
  RcandProcess rcand(operator_config());
  const Ctl ctl{std::to_string(rcand.port())};
  const auto moved = ctl({"move", "--linear", "0.3", "--duration", "200", "--json"}, "user-token");
  INFO(moved.err);
  CHECK(moved.exit_code == 0);
  CHECK(json::parse(moved.out)["linear"] == 0.3);
  CHECK(json::parse(moved.out)["angular"] == 0.0);  // left out: 0

  const auto too_fast = ctl({"move", "--linear", "5"}, "user-token");
  CHECK(too_fast.exit_code == 1);
  CHECK(too_fast.err.find("linear") != std::string::npos);
  CHECK(ctl({"move"}, "user-token").exit_code == 2);                                          // nothing to do
  CHECK(ctl({"move", "--linear", "fast"}, "user-token").exit_code == 2);                      // not a number
  CHECK(ctl({"move", "--linear", "0.1", "--duration", "2.5"}, "user-token").exit_code == 2);  // not whole ms
  CHECK(ctl({"move", "--angular", "0.2"}, "guest-token").exit_code == 1);                     // no control scope

  // Input ends at once: one move is sent, then the release stops the motors.
  const auto held = ctl({"move", "--linear", "0.2", "--hold"}, "user-token", "");
  CHECK(held.exit_code == 0);
  CHECK(held.out == "released: stopped\n");
  const auto drive = rcand.json("GET", "/api/drivers/drive0", "guest-token")["status"];
  INFO(drive.dump());
  CHECK(drive["left"] == 0.0);
  CHECK(drive["right"] == 0.0);
}

TEST_CASE("rcanctl nav go, status and cancel") {
  RcandProcess rcand(operator_config());
  const Ctl ctl{std::to_string(rcand.port())};
  const auto started = ctl({"nav", "go", "--distance", "5", "--heading", "0", "--speed", "0.2", "--json"}, "user-token");
  REQUIRE(started.exit_code == 0);
  const auto job = json::parse(started.out)["job_id"];
  const auto status = ctl({"nav", "status", "--json"}, "guest-token");
  CHECK(status.exit_code == 0);
  CHECK(json::parse(status.out)["job_id"] == job);
  const auto table = ctl({"nav", "status"}, "guest-token");
  CHECK(table.out.rfind("JOB", 0) == 0);
  CHECK(table.out.find(job.get<std::string>()) != std::string::npos);
  const auto cancelled = ctl({"nav", "cancel"}, "user-token");
  CHECK(cancelled.exit_code == 0);
  CHECK(cancelled.out == "job cancelled\n");
  CHECK(ctl({"nav", "go"}, "user-token").exit_code == 2);  // --distance is required
  CHECK(ctl({"nav"}, "user-token").exit_code == 2);
  const auto refused = ctl({"nav", "go", "--distance", "1", "--speed", "7"}, "user-token");
  CHECK(refused.exit_code == 1);
  CHECK(refused.err.find("speed") != std::string::npos);
}

TEST_CASE("rcanctl plugins and audit") {
  RcandProcess rcand(operator_config());
  const Ctl ctl{std::to_string(rcand.port())};
  const auto plugins = ctl({"plugins"}, "guest-token");
  CHECK(plugins.exit_code == 0);
  CHECK(plugins.out.rfind("ID", 0) == 0);
  CHECK(plugins.out.find("capability:teleop") != std::string::npos);
  CHECK(plugins.out.find("loaded") != std::string::npos);

  CHECK(ctl({"stop"}, "guest-token").exit_code == 0);  // something to audit
  CHECK(ctl({"stop"}, "guest-token").exit_code == 0);  // a repeat while latched: counted into that entry
  const auto audit = ctl({"audit", "--limit", "5"}, "owner-token");
  CHECK(audit.exit_code == 0);
  CHECK(audit.out.rfind("SEQ", 0) == 0);
  CHECK(audit.out.find("guest-principal") != std::string::npos);
  CHECK(audit.out.find("POST /api/stop (x2)") != std::string::npos);
  const auto lines = ctl({"audit", "--json"}, "owner-token");
  CHECK(json::parse(lines.out.substr(0, lines.out.find('\n'))).contains("seq"));
  CHECK(ctl({"audit"}, "guest-token").exit_code == 1);  // the audit log needs the config scope
  CHECK(ctl({"audit", "--limit", "0"}, "owner-token").exit_code == 2);
}

TEST_CASE("rcanctl status exits 1 for a robot that answers but reports a fault") {
  {
    RcandProcess healthy(operator_config());
    CHECK(Ctl{std::to_string(healthy.port())}({"status"}, "guest-token").exit_code == 0);
  }
  // A capability whose start() throws is failed (a request handler that throws no longer fails its capability).
  auto config = operator_config();
  const std::string faulty = "org.rcand.test.faulty";
  config["rcan_protocol"]["capabilities"].push_back(faulty);
  config["runtime"]["capabilities"][faulty] = {{"hook", "start"}, {"fault", "throw"}};
  RcandProcess rcand(config, {plugin_dir(), test_plugin_dir() / "faults"});
  const Ctl ctl{std::to_string(rcand.port())};
  const auto faulted = ctl({"status"}, "guest-token");
  CHECK(faulted.exit_code == 1);
  CHECK(faulted.out.find("state error") != std::string::npos);
}

TEST_CASE("rcanctl doctor names what is wrong and the command that fixes it") {
  RcandProcess rcand(operator_config());
  const std::string port = std::to_string(rcand.port());
  auto doctor = [&](const std::string& config_file) {
    const auto result = run_tool(
        rcanctl_binary(), {"doctor", "--config", config_file, "--rcand", rcand_binary(), "--plugin-path", plugin_dir().string(),
                           "--as-user", "root", "--port", port, "--token", "owner-token", "--json"});
    std::map<std::string, json> findings;
    std::istringstream lines(result.out);
    for (std::string line; std::getline(lines, line);) {
      const auto finding = json::parse(line);
      findings[finding["check"].get<std::string>()] = finding;
    }
    return findings;
  };
  const std::string config = (rcand.dir().path() / "robot.rcan.yaml").string();
  auto findings = doctor(config);
  INFO(json(findings).dump());
  for (const char* check : {"config", "robot", "e-stop", "plugins", "mDNS", "clock"})
    CHECK_MESSAGE(findings.count(check) == 1, check);
  for (const char* check : {"config", "robot", "e-stop", "plugins"}) CHECK_MESSAGE(findings[check]["ok"] == true, check);

  CHECK(rcand.json("POST", "/api/stop", "guest-token", "{}")["motors_stopped"] == true);
  findings = doctor(config);
  CHECK(findings["e-stop"]["ok"] == false);
  CHECK(findings["e-stop"]["fix"].get<std::string>().find("rcanctl estop clear") != std::string::npos);

  const TempDir dir;
  std::ifstream in(config);
  std::string yaml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  yaml.replace(yaml.find("\"rcan_protocol\""), std::string("\"rcan_protocol\"").size(), "\"rcan_protocl\"");  // JSON is YAML
  findings = doctor(dir.write("robot.rcan.yaml", yaml).string());
  CHECK(findings["config"]["ok"] == false);
  CHECK(findings["config"]["detail"].get<std::string>().find("did you mean 'rcan_protocol'") != std::string::npos);
  CHECK(findings["config"]["fix"].get<std::string>().find("--check-config") != std::string::npos);

  // rcand is run without a shell: a path with a quote and a space is checked as it is.
  std::ifstream good(config);
  const auto quoted = rcand.dir().write("it's a robot.rcan.yaml", std::string((std::istreambuf_iterator<char>(good)), {}));
  findings = doctor(quoted.string());
  CHECK(findings["config"]["ok"] == true);
  // The fix names such a path so that it can be pasted into a shell.
  const auto broken = dir.write("it's broken.rcan.yaml", yaml);
  findings = doctor(broken.string());
  CHECK(findings["config"]["ok"] == false);
  const std::string pasteable = "'" + dir.path().string() + "/it'\\''s broken.rcan.yaml'";
  CHECK(findings["config"]["fix"].get<std::string>().find("edit " + pasteable + ", then:") != std::string::npos);
  const auto missing = run_tool(rcanctl_binary(), {"doctor", "--config", quoted.string(), "--rcand", "/nonexistent/rcand",
                                                   "--port", port, "--token", "owner-token", "--json"});
  CHECK(missing.exit_code == 1);
  CHECK(missing.out.find("cannot run /nonexistent/rcand: No such file or directory") != std::string::npos);
}
