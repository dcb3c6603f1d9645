// mDNS for real (docs/protocol.md §5, §9): robots publish `_rcan._tcp` through avahi-daemon in network namespaces and are
// found from another namespace; TXT status follows the e-stop; the service goes with rcand and comes back after an
// avahi-daemon restart; a taken name is replaced; swarm "*.local" hosts resolve through mDNS with the ip fallback.
// Where the machine cannot make namespaces (or lacks avahi), each test says so and skips.
#include <doctest/doctest.h>

#include <chrono>
#include <set>
#include <sstream>
#include <thread>

#include "avahi_lab.hpp"
#include "swarm_lab.hpp"

using namespace rcand::test;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

// doctest 2.4 has no run-time skip: the test says so in the output and ends without assertions.
#define SKIP_WITHOUT_LAB(lab)                                                         \
  if (!(lab).available()) {                                                           \
    MESSAGE("SKIPPED: no mDNS lab on this machine: " << (lab).why_not());             \
    return;                                                                           \
  }

json mdns_robot(const AvahiLab& lab, int i, const std::string& name) {
  auto config = swarm_robot_config(name);
  config["runtime"]["listen"]["address"] = lab.address(i);
  config["rcan_protocol"]["enable_mdns"] = true;
  return config;
}

// Browses from namespace `from` until `accept` holds for what is seen, or the deadline passes.
template <class Accept>
std::map<std::string, std::map<std::string, std::string>> browse_until(const AvahiLab& lab, int from, Accept accept,
                                                                       std::chrono::seconds deadline = std::chrono::seconds(20)) {
  const auto end = Clock::now() + deadline;
  auto seen = lab.browse(from);
  while (!accept(seen) && Clock::now() < end) seen = lab.browse(from);
  return seen;
}

std::string join(const json& list) {
  std::string out;
  for (const auto& item : list) out += (out.empty() ? "" : ",") + item.get<std::string>();
  return out;
}

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

}  // namespace

TEST_CASE("mdns: a robot is found from another namespace with the registry's TXT; status follows the e-stop; stopping withdraws it") {
  AvahiLab lab(2);
  SKIP_WITHOUT_LAB(lab);
  const std::string name = "rover-" + std::to_string(::getpid());
  auto robot = std::make_unique<RcandProcess>(mdns_robot(lab, 1, name), lab.launcher(1), lab.address(1));

  auto seen = browse_until(lab, 2, [&](const auto& s) { return s.count(name) != 0; });
  REQUIRE_MESSAGE(seen.count(name) == 1, robot->stderr_text());
  auto txt = seen[name];
  CHECK(txt["@address"] == lab.address(1));
  CHECK(txt["@port"] == std::to_string(robot->port()));

  // Exactly the docs/protocol.md §5 keys, each equal to the DISCOVER document's txt_record; caps == capabilities[] (§9.5).
  const json discovery = robot->json("GET", "/api/discovery");
  std::set<std::string> keys;
  for (const auto& [key, value] : txt)
    if (key[0] != '@') keys.insert(key);
  CHECK(keys == std::set<std::string>{"ruri", "model", "caps", "roles", "role", "version", "name", "status"});
  for (const auto& key : keys) CHECK_MESSAGE(txt[key] == discovery["txt_record"][key].get<std::string>(), key);
  CHECK(txt["caps"] == join(discovery["capabilities"]));
  CHECK(txt["name"] == name);
  CHECK(txt["status"] == "idle");
  CHECK(txt["version"] == "1.3.0");

  // rcanctl discover from the other namespace: the same robot, its DISCOVER document agreeing with its TXT.
  const auto found = lab.run(2, rcanctl_binary(), {"discover", "--json", "--timeout", "5"});
  CHECK_MESSAGE(found.exit_code == 0, found.out << found.err);
  json entry;
  std::istringstream lines(found.out);
  for (std::string line; std::getline(lines, line);)
    if (auto doc = json::parse(line, nullptr, false); doc.is_object() && doc.value("name", "") == name) entry = doc;
  REQUIRE_MESSAGE(entry.is_object(), found.out << found.err);
  CHECK(entry["ruri"] == discovery["ruri"]);
  CHECK(entry["address"] == lab.address(1));
  CHECK(entry["port"] == robot->port());
  CHECK(entry["caps"] == discovery["capabilities"]);
  CHECK(entry["status"] == "idle");
  CHECK(entry["consistent"] == true);
  const auto table = lab.run(2, rcanctl_binary(), {"discover", "--timeout", "5"});
  CHECK(table.out.find("NAME") != std::string::npos);
  CHECK(table.out.find(name) != std::string::npos);

  // rcanctl reaches it by its "*.local" name through avahi-daemon (no libnss-mdns on this machine).
  const std::string local_name = lab.host_name(1) + ".local", port = std::to_string(robot->port());
  const auto by_name =
      lab.run(2, rcanctl_binary(), {"status", "--host", local_name, "--port", port, "--token", "guest-token", "--json"});
  CHECK_MESSAGE(by_name.exit_code == 0, by_name.out << by_name.err);
  CHECK(json::parse(by_name.out, nullptr, false).value("state", "") == "idle");
  const auto estop = lab.run(2, rcanctl_binary(), {"estop", "--host", local_name, "--port", port, "--token", "guest-token"});
  CHECK_MESSAGE(estop.exit_code == 0, estop.out << estop.err);
  CHECK(estop.out == "not latched\n");
  const auto nobody = lab.run(2, rcanctl_binary(),
                              {"estop", "--host", "nobody-" + std::to_string(::getpid()) + ".local", "--port", port, "--token",
                               "guest-token", "--timeout", "1000"});
  CHECK(nobody.exit_code == 1);
  CHECK(nobody.err.find(".local: ") != std::string::npos);

  // An e-stop shows in TXT status within 5 s (docs/protocol.md §5).
  int status = 0;
  robot->json("POST", "/api/stop", "guest-token", "{}", &status);
  REQUIRE(status == 200);
  const auto stopped = Clock::now();
  seen = browse_until(lab, 2, [&](auto& s) { return s.count(name) && s.at(name).count("status") && s.at(name).at("status") == "estop"; },
                      std::chrono::seconds(10));
  const auto took = Clock::now() - stopped;
  REQUIRE(seen.count(name) == 1);
  CHECK(seen[name]["status"] == "estop");
  CHECK_MESSAGE(took < std::chrono::seconds(5), std::chrono::duration<double>(took).count() << " s");

  // Stopping rcand withdraws the service (the daemon's goodbye removes it from the other side's cache).
  robot.reset();
  seen = browse_until(lab, 2, [&](const auto& s) { return s.count(name) == 0; });
  CHECK(seen.count(name) == 0);
}

TEST_CASE("mdns: rcand serves without avahi-daemon, registers when it appears, and again after it was killed and restarted") {
  AvahiLab lab(2);
  SKIP_WITHOUT_LAB(lab);
  const std::string name = "phoenix-" + std::to_string(::getpid());
  lab.kill_daemon(1);
  RcandProcess robot(mdns_robot(lab, 1, name), lab.launcher(1), lab.address(1));
  int status = 0;
  robot.json("GET", "/health", "", "", &status);
  CHECK(status == 200);  // HTTP serves with no daemon
  CHECK(lab.browse(2).count(name) == 0);

  REQUIRE(lab.start_daemon(1));
  auto seen = browse_until(lab, 2, [&](const auto& s) { return s.count(name) != 0; });
  CHECK_MESSAGE(seen.count(name) == 1, robot.stderr_text());

  lab.kill_daemon(1);  // a crash: no goodbyes
  robot.json("GET", "/api/discovery", "", "", &status);
  CHECK(status == 200);
  REQUIRE(lab.start_daemon(1));
  // The other side may still cache the old record: wait for the fresh one, which only a re-registration gives.
  const auto restarted = Clock::now();
  seen = browse_until(lab, 2, [&](const auto& s) { return s.count(name) != 0; });
  CHECK_MESSAGE(seen.count(name) == 1, robot.stderr_text());
  // ... and the robot's own daemon (fresh, empty) lists it only if rcand registered again.
  seen = browse_until(lab, 1, [&](const auto& s) { return s.count(name) != 0; });
  CHECK_MESSAGE(seen.count(name) == 1, robot.stderr_text());
  MESSAGE("re-registered within " << std::chrono::duration<double>(Clock::now() - restarted).count() << " s");

  const std::string log = robot.stderr_text();
  CHECK(count(log, "avahi-daemon is not running") == 1);  // logged once, not per retry
  CHECK(count(log, "lost avahi-daemon") == 1);
  CHECK(count(log, "avahi-daemon is available again") == 2);
}

TEST_CASE("mdns: two robots with the same robot_name: the second publishes the Avahi alternative name and logs it") {
  AvahiLab lab(2);
  SKIP_WITHOUT_LAB(lab);
  const std::string name = "twin-" + std::to_string(::getpid());
  RcandProcess first(mdns_robot(lab, 1, name), lab.launcher(1), lab.address(1));
  auto seen = browse_until(lab, 2, [&](const auto& s) { return s.count(name) != 0; });
  REQUIRE(seen.count(name) == 1);

  RcandProcess second(mdns_robot(lab, 2, name), lab.launcher(2), lab.address(2));
  const std::string alternative = name + " #2";
  seen = browse_until(lab, 1, [&](const auto& s) { return s.count(name) && s.count(alternative); });
  REQUIRE_MESSAGE(seen.count(alternative) == 1, second.stderr_text());
  CHECK(seen[name]["@address"] == lab.address(1));
  CHECK(seen[alternative]["@address"] == lab.address(2));
  CHECK(seen[alternative]["name"] == name);  // the TXT keeps the robot's own name
  CHECK(second.stderr_text().find("publishing as '" + alternative + "'") != std::string::npos);
  CHECK(first.stderr_text().find("publishing as") == std::string::npos);
}

TEST_CASE("mdns: swarm *.local hosts resolve through avahi, the static ip is the fallback, a broadcast stop stays inside 500 ms") {
  AvahiLab lab(3);
  SKIP_WITHOUT_LAB(lab);
  auto at = [&](const std::string& name, int i) {
    auto config = swarm_robot_config(name);
    config["runtime"]["listen"]["address"] = lab.address(i);
    return config;
  };
  auto bravo = std::make_unique<RcandProcess>(at("bravo", 2), lab.launcher(2), lab.address(2));
  RcandProcess charlie(at("charlie", 3), lab.launcher(3), lab.address(3));
  TempDir dir;
  // bravo: by its mDNS name only (its `ip` is wrong: the fallback would fail). charlie: an mDNS name nobody
  // answers, with the right `ip`.
  const std::string wrong_ip = lab.address(99);
  const auto swarm_file = dir.write(
      "swarm.yaml", swarm_yaml({SwarmEntry("bravo", lab.host_name(2) + ".local", bravo->port(), "owner-token", {}, wrong_ip),
                                SwarmEntry("charlie", "nobody-" + std::to_string(::getpid()) + ".local", charlie.port(),
                                           "owner-token", {}, lab.address(3))}));
  auto config = swarm_robot_config("alpha", swarm_file);
  config["runtime"]["listen"]["address"] = lab.address(1);
  RcandProcess alpha(config, lab.launcher(1), lab.address(1));

  auto broadcast_stop = [&](double* elapsed_ms) {
    const auto sent = Clock::now();
    const auto response = alpha.request("POST", "/api/stop", "owner-token", "{}", {{"X-Swarm-Broadcast", "true"}});
    *elapsed_ms = std::chrono::duration<double, std::milli>(Clock::now() - sent).count();
    return json::parse(response.body, nullptr, false);
  };
  for (int round = 0; round < 3; ++round) {  // the first from a cold cache, then from the cache
    double elapsed_ms = 0;
    const json doc = broadcast_stop(&elapsed_ms);
    REQUIRE_MESSAGE(doc.contains("nodes"), doc.dump() << alpha.stderr_text());
    std::map<std::string, json> by_name;
    for (const auto& node : doc["nodes"]) by_name[node["name"]] = node;
    CHECK_MESSAGE(by_name["bravo"]["ok"] == true, by_name["bravo"].dump());
    CHECK(by_name["bravo"]["address"] == lab.address(2) + ":" + std::to_string(bravo->port()));  // found through mDNS
    CHECK_MESSAGE(by_name["charlie"]["ok"] == true, by_name["charlie"].dump());
    CHECK(by_name["charlie"]["address"] == lab.address(3) + ":" + std::to_string(charlie.port()));  // the ip fallback
    CHECK_MESSAGE(elapsed_ms < 500.0, "round " << round << ": " << elapsed_ms << " ms");
    alpha.request("POST", "/api/estop/clear", "owner-token");
  }

  // A peer that is gone: the broadcast still answers inside 500 ms (resolution from the cache, connection refused
  // or timed out within the per-peer budget).
  bravo.reset();
  double elapsed_ms = 0;
  const json doc = broadcast_stop(&elapsed_ms);
  CHECK_MESSAGE(elapsed_ms < 500.0, elapsed_ms << " ms " << doc.dump());
}

TEST_CASE("mdns: with enable_mdns and no system bus at all, rcand serves, logs the outage once and stops promptly") {
  auto config = swarm_robot_config("nobus-" + std::to_string(::getpid()));
  config["rcan_protocol"]["enable_mdns"] = true;
  // No lab needed: a system bus address nobody listens on, whatever this machine runs.
  RcandProcess robot(config, {"/usr/bin/env", "DBUS_SYSTEM_BUS_ADDRESS=unix:path=/nonexistent/rcand-test/bus"}, "127.0.0.1");
  int status = 0;
  const json discovery = robot.json("GET", "/api/discovery", "", "", &status);
  CHECK(status == 200);
  CHECK(discovery["txt_record"]["status"] == "idle");
  robot.json("POST", "/api/stop", "guest-token", "{}", &status);
  CHECK(status == 200);
  const auto stopping = Clock::now();
  CHECK(robot.stop() == 0);
  CHECK(Clock::now() - stopping < std::chrono::seconds(3));
  const std::string log = robot.stderr_text();
  CHECK_MESSAGE(count(log, "mDNS publisher: cannot reach the system D-Bus") == 1, log);
  CHECK(log.find("withdrew") == std::string::npos);  // nothing was published
}
