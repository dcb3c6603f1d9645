// The audit log against a running rcand: user-supplied text is bounded (no amplification of a huge "type" into
// memory, the audit file or the logs), the file rotates by size, the sequence continues across restarts, and an
// entry in flight at kill -9 is already in the file (its pending line, written before dispatch).
#include <doctest/doctest.h>

#include <atomic>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <thread>

#include "rcand_process.hpp"
#include "sanitized_build.hpp"
#include "swarm_lab.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

std::string audit_test_read(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

std::vector<json> audit_test_lines(const std::filesystem::path& file) {
  std::vector<json> lines;
  std::istringstream in(audit_test_read(file));
  for (std::string line; std::getline(in, line);)
    if (!line.empty()) lines.push_back(json::parse(line, nullptr, false));
  return lines;
}

std::uintmax_t audit_test_file_size(const std::filesystem::path& file) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(file, ec);
  return ec ? 0 : size;
}

}  // namespace

TEST_CASE("audit: 300 requests with a 1 MB \"type\" grow neither the audit file, the log nor the memory") {
  auto config = sim_config();
  config["rcan_protocol"]["capabilities"] = {"status", "teleop", "nav", "com.acme.gripper"};
  TempDir files;
  const auto audit_file = files.path() / "audit.jsonl";
  config["runtime"]["audit_file"] = audit_file.string();
  RcandProcess rcand(config);

  const std::string huge_type(1000 * 1000, 'T');  // the body limit is 1 MiB
  const std::string body = json{{"type", huge_type}, {"distance_m", "not a number"}}.dump();
  // Warm up (first-use allocations, thread stacks) so the figure measures what the requests leave behind.
  for (int i = 0; i < 5; ++i) rcand.request("POST", "/api/nav/waypoint", "user-token", body);
  const long rss_before = resident_kb(rcand.pid());
  const auto stderr_before = audit_test_file_size(rcand.dir().path() / "stderr");
  // The sanitizer build checks behaviour only (its RSS is ASan's): 30 unbounded entries would still be 30 MB.
  const int requests = kSanitizedBuild ? 30 : 300;
  for (int i = 0; i < requests; ++i) {
    const auto response = rcand.request("POST", "/api/nav/waypoint", "user-token", body);
    REQUIRE(response.status == 400);
    if (i == 0) CHECK(response.body.size() < 4096);  // the error body does not echo it either
  }
  const long rss_after = resident_kb(rcand.pid());
  const auto stderr_grew = audit_test_file_size(rcand.dir().path() / "stderr") - stderr_before;
  const auto audit_bytes = audit_test_file_size(audit_file);
  MESSAGE("RSS before " << rss_before << " kB, after " << rss_after << " kB (+" << rss_after - rss_before << " kB); audit file "
                        << audit_bytes << " bytes; stderr +" << stderr_grew << " bytes");
  REQUIRE(rss_before > 0);
  if (!kSanitizedBuild) CHECK(rss_after - rss_before < 64 * 1024);  // was +314 MB: each entry kept the whole type
  CHECK(audit_bytes < 2 * 1024 * 1024);                             // was 315 MB: 610 entries x 2 lines, each bounded
  CHECK(stderr_grew < 2 * 1024 * 1024);

  const auto audit = rcand.json("GET", "/api/audit?limit=10", "owner-token");
  REQUIRE(audit["entries"].size() == 10);
  for (const auto& entry : audit["entries"]) CHECK(entry["event"].get<std::string>().size() <= 300);
  for (const auto& line : audit_test_lines(audit_file)) {
    REQUIRE(line.is_object());
    CHECK(line.dump().size() < 2048);
  }
}

TEST_CASE("audit: the file rotates by size, keeps runtime.audit_keep_files, and no seq is missing") {
  auto config = sim_config();
  TempDir files;
  const auto audit_file = files.path() / "audit.jsonl";
  config["runtime"]["audit_file"] = audit_file.string();
  config["runtime"]["audit_max_bytes"] = 4096;
  config["runtime"]["audit_keep_files"] = 2;
  RcandProcess rcand(config);
  for (int i = 0; i < 40; ++i) {
    int status = 0;
    rcand.json("POST", "/api/estop/clear", "owner-token", "", &status);
    REQUIRE(status == 200);
  }
  const auto first = std::filesystem::path(audit_file.string() + ".1");
  const auto second = std::filesystem::path(audit_file.string() + ".2");
  CHECK(std::filesystem::exists(first));
  CHECK(std::filesystem::exists(second));
  CHECK_FALSE(std::filesystem::exists(audit_file.string() + ".3"));
  for (const auto& file : {audit_file, first, second}) CHECK(audit_test_file_size(file) <= 4096);

  // Oldest to newest: .2, .1, the file. Every seq from the first kept to the last has both its lines.
  std::map<std::uint64_t, std::set<std::string>> kinds;
  for (const auto& file : {second, first, audit_file})
    for (const auto& line : audit_test_lines(file)) {
      REQUIRE(line.is_object());
      kinds[line["seq"].get<std::uint64_t>()].insert(line["kind"].get<std::string>());
    }
  REQUIRE(!kinds.empty());
  CHECK(kinds.rbegin()->first == 40);
  std::uint64_t expected = kinds.begin()->first;
  for (const auto& [seq, seen] : kinds) {
    CHECK(seq == expected++);
    if (seq != kinds.begin()->first)
      CHECK(seen == std::set<std::string>{"entry", "outcome"});  // the oldest may have lost its pending line
  }
}

TEST_CASE("audit: seq continues across a restart, and an entry in flight at kill -9 is in the file as pending") {
  TempDir shared;
  const auto audit_file = shared.path() / "audit.jsonl";
  auto config = sim_config();
  const std::string capability = "org.rcand.test.faulty";
  config["rcan_protocol"]["capabilities"].push_back(capability);
  config["runtime"]["capabilities"][capability] = {{"hook", "handler"}, {"fault", "hang"}};
  config["runtime"]["handler_timeout_ms"] = 60000;  // the request stays in flight until the kill
  config["runtime"]["audit_file"] = audit_file.string();
  config["runtime"]["state_dir"] = (shared.path() / "state").string();
  const std::vector<std::filesystem::path> plugins{plugin_dir(), test_plugin_dir() / "faults"};

  std::uint64_t last_seq = 0;
  {
    RcandProcess first(config, plugins);
    for (int i = 0; i < 3; ++i) first.request("POST", "/api/estop/clear", "owner-token");
    CHECK(first.stop() == 0);
  }
  for (const auto& line : audit_test_lines(audit_file)) last_seq = std::max(last_seq, line["seq"].get<std::uint64_t>());
  CHECK(last_seq == 3);

  std::uint64_t pending_seq = 0;
  {
    RcandProcess second(config, plugins);
    // Its seq continues the file's.
    const auto cleared = second.request("POST", "/api/estop/clear", "owner-token", "", {{"X-Message-Id", "after-restart"}});
    CHECK(cleared.status == 200);
    // A request whose handler never returns: in flight until the kill.
    std::thread in_flight([&] {
      try {
        second.request("POST", "/api/cap/" + capability + "/work", "owner-token", "{}", {{"X-Message-Id", "in-flight-at-kill"}});
      } catch (...) {  // the connection dies with the process
      }
    });
    // Wait for its pending line, which record() writes before dispatch (bounded against a hang).
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (audit_test_read(audit_file).find("in-flight-at-kill") == std::string::npos &&
           std::chrono::steady_clock::now() < deadline)
      std::this_thread::yield();
    second.kill_hard();
    in_flight.join();
  }
  int in_flight_lines = 0;
  for (const auto& line : audit_test_lines(audit_file)) {
    REQUIRE(line.is_object());
    if (line.value("message_id", "") == "after-restart") CHECK(line["seq"] == last_seq + 1);
    if (line.value("message_id", "") != "in-flight-at-kill") continue;
    ++in_flight_lines;
    CHECK(line["kind"] == "entry");
    CHECK(line["outcome"] == "pending");
    CHECK(line["event"] == "POST /api/cap/" + capability + "/work");
    pending_seq = line["seq"].get<std::uint64_t>();
  }
  CHECK(in_flight_lines == 1);  // the pending line, and no outcome: it never finished
  CHECK(pending_seq == last_seq + 2);

  // The next run (latched: the last one was killed) continues after the pending entry.
  RcandProcess third(config, plugins);
  CHECK(third.json("GET", "/api/estop", "guest-token")["estopped"] == true);
  const auto newest = third.json("GET", "/api/audit?limit=1", "owner-token")["entries"][0];
  CHECK(newest["event"] == "e-stop latched at startup");
  CHECK(newest["seq"] == pending_seq + 1);
}

// Issue 28 #7: 2,000 stops a second from one GUEST pushed a USER's move out of memory and out of the rotated files.
TEST_CASE("audit: a GUEST's stop flood keeps a USER's move in memory and in the file; repeats are one entry") {
  TempDir files;
  const auto audit_file = files.path() / "audit.jsonl";
  const auto swarm_file = files.write("swarm.yaml", swarm_yaml({{"bravo", "127.0.0.1", 9}}));
  auto config = swarm_robot_config("alpha", swarm_file);
  config["runtime"]["audit_file"] = audit_file.string();
  config["runtime"]["audit_max_bytes"] = 4096;
  config["runtime"]["audit_keep_files"] = 1;
  RcandProcess robot(config);

  const auto moved =
      robot.request("POST", "/api/action", "user-token", R"({"type":"move","linear":0.1,"angular":0.0,"duration_ms":100})",
                    {{"X-Message-Id", "user-move"}});
  CHECK(moved.status == 200);
  constexpr int kStops = 2000;
  for (int i = 0; i < kStops; ++i)
    REQUIRE(robot.request("POST", "/api/stop", "guest-token", "", {{"X-Message-Id", "g-" + std::to_string(i)}}).status == 200);
  // Unknown swarm nodes: audited 404s while the principal's budget lasts, then 429 (logged, not audited).
  int not_found = 0, limited = 0;
  for (int i = 0; i < 200; ++i) {
    const auto status = robot.request("POST", "/api/swarm/nobody-" + std::to_string(i) + "/stop", "guest-token").status;
    not_found += status == 404;
    limited += status == 429;
  }
  CHECK(not_found + limited == 200);
  CHECK(limited > 0);
  CHECK(not_found >= 10);

  const auto audit = robot.json("GET", "/api/audit?limit=10000", "owner-token");
  int moves = 0, stop_entries = 0, unknown_entries = 0;
  for (const auto& entry : audit["entries"]) {
    const std::string event = entry["event"];
    if (entry["message_id"] == "user-move") ++moves;
    if (event.starts_with("POST /api/swarm/nobody-")) ++unknown_entries;
    if (event != "POST /api/stop") continue;
    ++stop_entries;
    CHECK(entry["principal"] == "guest-principal");
    CHECK(entry["message_id"] == "g-0");  // the stop that latched; every later one repeats it
    CHECK(entry["count"] == kStops);
    CHECK(entry["last_message_id"] == "g-" + std::to_string(kStops - 1));
    CHECK(entry["outcome"] == "ok");
  }
  CHECK(moves == 1);
  CHECK(stop_entries == 1);
  CHECK(unknown_entries == not_found);
  CHECK(audit["dropped"] == 0);

  // The move's lines are still in the main file (it was rotated out by the stops' lines before); the stops went to
  // their own file, which rotated.
  int move_lines = 0;
  for (const auto& line : audit_test_lines(audit_file)) move_lines += line.value("message_id", "") == "user-move";
  CHECK(move_lines == 2);  // pending, then its outcome
  CHECK_FALSE(std::filesystem::exists(audit_file.string() + ".1"));
  CHECK(std::filesystem::exists(files.path() / "audit.stops.jsonl"));
  CHECK(audit["stops_file"] == (files.path() / "audit.stops.jsonl").string());
}
