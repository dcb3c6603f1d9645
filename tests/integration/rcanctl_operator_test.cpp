// rcanctl's daily-work subcommands (issue 19) against a real rcand: the e-stop, moves (hold-to-move included), nav,
// plugins, the audit log, and `status` exiting 1 for a robot that reports a fault. Exit codes: 0 / 1 / 2.
#include <doctest/doctest.h>

#include <fstream>
#include <iterator>
#include <map>
#include <regex>
#include <set>
#include <sstream>

#include "rcand_process.hpp"
#include "sanitized_build.hpp"

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
  CHECK(ctl(with_stop_timeout({"stop"}), "guest-token").exit_code == 0);
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

  CHECK(ctl(with_stop_timeout({"stop"}), "guest-token").exit_code == 0);  // something to audit
  CHECK(ctl(with_stop_timeout({"stop"}), "guest-token").exit_code == 0);  // a repeat while latched: counted into that entry
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
  // The config leaves mDNS off: its check is skipped, not failed (issue 29: doctor exited 1 on the bundled robot).
  CHECK(findings["mDNS"]["ok"] == true);
  CHECK(findings["mDNS"]["skipped"] == true);

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

namespace {

constexpr const char* kAbsentU2d2 = "/dev/rcanctl-test-no-such-u2d2";

// An arm on a Dynamixel bus that is not plugged in: the robot is in error because of driver arm0.
json robot_with_unplugged_arm() {
  json config = operator_config();
  config["physics"]["kinematics"] = json::array({{{"joint", "shoulder"}, {"min_deg", -90}, {"max_deg", 90}}});
  config["drivers"].push_back({{"id", "arm0"},
                               {"protocol", "dynamixel"},
                               {"port", kAbsentU2d2},
                               {"servos", json::array({{{"id", 1}, {"joint", "shoulder"}}})}});
  config["rcan_protocol"]["capabilities"].push_back("arm");
  return config;
}

}  // namespace

TEST_CASE("rcanctl status, plugins and doctor show a failed driver's device, OS error and the fix") {
  RcandProcess rcand(robot_with_unplugged_arm());
  const Ctl ctl{std::to_string(rcand.port())};
  const std::string failure = std::string("driver arm0 failed: cannot open ") + kAbsentU2d2 + ": No such file or directory";

  const auto status = ctl({"status"}, "guest-token");
  INFO(status.out);
  CHECK(status.exit_code == 1);
  CHECK(status.out.find(failure) != std::string::npos);
  CHECK(status.out.find("fix: is the U2D2 plugged in?") != std::string::npos);
  const auto status_json = ctl({"status", "--json"}, "guest-token");
  const json node = json::parse(status_json.out);
  CHECK(node["error"].get<std::string>().find(failure + "; fix: is the U2D2 plugged in?") != std::string::npos);
  CHECK(node["problems"][0]["driver"] == "arm0");
  CHECK(node["problems"][0]["state"] == "failed");

  // The library loaded, but its one instance failed: the listing shows the instance, why, and the fix.
  const auto plugins = ctl({"plugins"}, "guest-token");
  INFO(plugins.out);
  CHECK(plugins.exit_code == 0);
  std::istringstream lines(plugins.out);
  std::string dynamixel_row;
  for (std::string line; std::getline(lines, line);)
    if (line.find("driver:arm0") != std::string::npos) dynamixel_row = line;
  CHECK(dynamixel_row.find("org.rcand.dynamixel") == 0);
  CHECK(dynamixel_row.find(" loaded ") != std::string::npos);
  CHECK(dynamixel_row.find(" error ") != std::string::npos);   // the plugin's health
  CHECK(dynamixel_row.find(" failed ") != std::string::npos);  // the instance's state
  CHECK(dynamixel_row.find(kAbsentU2d2) != std::string::npos);
  CHECK(plugins.out.find(failure + "\n  fix: is the U2D2 plugged in?") != std::string::npos);

  // doctor no longer says "plugins ok": it names the instance and gives the robot's fix.
  const auto doctor =
      run_tool(rcanctl_binary(), {"doctor", "--config", (rcand.dir().path() / "robot.rcan.yaml").string(), "--rcand",
                                  rcand_binary(), "--plugin-path", plugin_dir().string(), "--as-user", "root", "--port",
                                  std::to_string(rcand.port()), "--token", "owner-token", "--json"});
  CHECK(doctor.exit_code == 1);
  json plugins_check;
  std::istringstream findings(doctor.out);
  for (std::string line; std::getline(findings, line);)
    if (const json finding = json::parse(line); finding["check"] == "plugins") plugins_check = finding;
  INFO(plugins_check.dump());
  CHECK(plugins_check["ok"] == false);
  CHECK(plugins_check["detail"].get<std::string>().find("org.rcand.dynamixel: " + failure) != std::string::npos);
  CHECK(plugins_check["fix"].get<std::string>().find("is the U2D2 plugged in?") == 0);
}

TEST_CASE("rcanctl for people: one clear line for a bad value, HOST:PORT, local times, what a command did") {
  auto config = operator_config();
  config["rcan_protocol"]["capabilities"].push_back("chat");
  RcandProcess rcand(config);
  const std::string port = std::to_string(rcand.port());
  const Ctl ctl{port};

  // A value that is no number: one line naming the option and the value; nothing sent.
  const auto fast = ctl({"move", "--linear", "fast"}, "user-token");
  CHECK(fast.exit_code == 2);
  CHECK(fast.err == "rcanctl move: --linear: must be a number, got 'fast' (see rcanctl move --help)\n");
  const auto sideways = ctl({"nav", "sideways"}, "user-token");
  CHECK(sideways.exit_code == 2);
  CHECK(sideways.err.find("unknown action 'sideways' (one of: go status cancel)") != std::string::npos);

  // --host HOST:PORT, as people write an address.
  const auto hosted = run_tool(rcanctl_binary(), {"status", "--host", "127.0.0.1:" + port, "--token", "guest-token", "--json"});
  INFO(hosted.err);
  CHECK(hosted.exit_code == 0);
  CHECK(json::parse(hosted.out)["address"] == "127.0.0.1:" + port);
  const auto estop_hosted = run_tool(rcanctl_binary(), {"estop", "--host", "127.0.0.1:" + port, "--token", "guest-token"});
  CHECK(estop_hosted.exit_code == 0);
  CHECK(run_tool(rcanctl_binary(), {"estop", "--host", "127.0.0.1:http", "--token", "guest-token"}).exit_code == 2);

  // Times in the local zone as ISO 8601; --json keeps the robot's number.
  CHECK(ctl(with_stop_timeout({"stop"}), "guest-token").exit_code == 0);
  const std::regex iso("[0-9]{4}-[0-9]{2}-[0-9]{2}T[0-9]{2}:[0-9]{2}:[0-9]{2}\\.[0-9]{3}[+-][0-9]{2}:[0-9]{2}");
  const auto latched = ctl({"estop"}, "guest-token");
  INFO(latched.out);
  CHECK(std::regex_search(latched.out, std::regex("^LATCHED since " + std::string("[0-9]{4}-[0-9]{2}-[0-9]{2}T"))));
  CHECK(std::regex_search(latched.out, iso));
  CHECK(json::parse(ctl({"estop", "--json"}, "guest-token").out)["since_ms"].is_number_integer());
  const auto audit = ctl({"audit", "--limit", "3"}, "owner-token");
  CHECK(audit.out.rfind("SEQ  TIME", 0) == 0);
  CHECK(std::regex_search(audit.out, iso));
  CHECK(ctl({"estop", "clear"}, "owner-token").exit_code == 0);

  // A command shows what the robot understood and what it did, not only "executed".
  const auto commanded = ctl({"command", "--instruction", "drive forward 1 m at speed 0.5"}, "user-token");
  INFO(commanded.out, commanded.err);
  CHECK(commanded.exit_code == 0);
  CHECK(commanded.out.find("understood: ") != std::string::npos);
  CHECK(commanded.out.find("  action: nav_waypoint (") != std::string::npos);
  CHECK(commanded.out.find("  request: POST /api/nav/waypoint") != std::string::npos);
  CHECK(commanded.out.find("distance_m 1") != std::string::npos);
  CHECK(commanded.out.find(" done") != std::string::npos);
}

namespace {

// The words of a help text that are options ("--json") or, under CLI11's "Subcommands:", actions.
struct HelpWords {
  std::set<std::string> options, actions;
};

HelpWords help_words(const std::string& help) {
  HelpWords words;
  const std::regex option("--[a-z][a-z0-9-]*");
  for (std::sregex_iterator it(help.begin(), help.end(), option), end; it != end; ++it) words.options.insert(it->str());
  std::istringstream lines(help);
  bool in_actions = false;
  for (std::string line; std::getline(lines, line);) {
    if (line == "Subcommands:") in_actions = true;
    else if (line.empty() || line.front() != ' ') in_actions = false;
    else if (in_actions && line.size() > 2 && line[2] != ' ') words.actions.insert(line.substr(2, line.find(' ', 2) - 2));
  }
  return words;
}

}  // namespace

TEST_CASE("rcanctl's man page covers every subcommand, action and option its parsers know") {
  std::ifstream page(std::string(RCAND_SOURCE_DIR) + "/packaging/man/rcanctl.1");
  REQUIRE(page.good());
  std::string man((std::istreambuf_iterator<char>(page)), {});
  // Troff escapes: "\-\-json" is "--json" on the page.
  for (std::size_t at; (at = man.find("\\-")) != std::string::npos;) man.replace(at, 2, "-");

  const auto top = run_tool(rcanctl_binary(), {"--help"});
  REQUIRE(top.exit_code == 0);
  std::vector<std::string> subcommands;  // rcanctl's own table: "  name   summary" under "subcommands:"
  std::istringstream lines(top.out.substr(top.out.find("subcommands:")));
  for (std::string line; std::getline(lines, line);)
    if (line.rfind("  ", 0) == 0 && line[2] != ' ') subcommands.push_back(line.substr(2, line.find(' ', 2) - 2));
  CHECK(subcommands.size() >= 14);
  for (const auto& subcommand : subcommands) {
    const std::string section = ".SS " + subcommand;
    CHECK_MESSAGE(man.find(section) != std::string::npos, section);
    const auto help = run_tool(rcanctl_binary(), {subcommand, "--help"});
    CHECK_MESSAGE(help.exit_code == 0, subcommand);
    HelpWords words = help_words(help.out);
    for (const auto& action : words.actions) {
      const std::string words_of_action = subcommand + " " + action;
      CHECK_MESSAGE(man.find(words_of_action) != std::string::npos, words_of_action);
      const auto action_help = run_tool(rcanctl_binary(), {subcommand, action, "--help"});
      CHECK_MESSAGE(action_help.exit_code == 0, words_of_action);
      words.options.merge(help_words(action_help.out).options);
    }
    for (const auto& option : words.options) {
      const std::string missing = subcommand + " " + option + " is not in rcanctl.1";
      CHECK_MESSAGE(man.find(option) != std::string::npos, missing);
    }
  }
}
