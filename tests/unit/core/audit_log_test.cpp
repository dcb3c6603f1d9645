// The audit log never loses an entry silently: rotation out of memory is counted, and the file keeps every one.
#include <doctest/doctest.h>

#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "kernel/audit/audit_log.hpp"

using namespace rcand;
using namespace rcand::kernel;

TEST_CASE("entries rotated out of the in-memory ring are counted as dropped") {
  AuditLog log(3);
  for (int i = 0; i < 5; ++i)
    log.finish(log.record({0, "p", "r", "m" + std::to_string(i), "POST /x", 1, "pending", {}, nullptr}), "ok");
  const auto doc = log.to_json(100);
  CHECK(doc["entries"].size() == 3);
  CHECK(doc["total"] == 5);
  CHECK(doc["dropped"] == 2);
  CHECK(log.dropped() == 2);
}

TEST_CASE("a plugin's note joins its entry, in memory and in the file, and never replaces the entry's own fields") {
  AuditLog log(4);
  const nlohmann::json note{{"ai", {{"provider", "grammar"}, {"thought_id", "th-1"}}}, {"outcome", "forged"}};
  log.finish(log.begin("alice", "m1", "POST /api/nav/waypoint", note), "ok");
  const auto entry = log.to_json(1)["entries"][0];
  CHECK(entry["ai"] == note["ai"]);
  CHECK(entry["outcome"] == "ok");
  CHECK(entry["principal"] == "alice");
}

TEST_CASE("with a file, every entry is appended twice: pending before dispatch, then its outcome under the same seq") {
  const auto file = std::filesystem::temp_directory_path() / ("rcand-audit-test-" + std::to_string(::getpid()) + ".jsonl");
  std::filesystem::remove(file);
  {
    AuditLog log(2);
    log.persist_to(file);
    for (int i = 0; i < 4; ++i) {
      const auto seq = log.record({0, "p", "r", "m" + std::to_string(i), "POST /x", 1, "pending", {}, nullptr});
      // The pending line is in the file before finish() (before the command is dispatched).
      std::ifstream before(file);
      std::string last, line;
      while (std::getline(before, line)) last = line;
      const auto pending = nlohmann::json::parse(last);
      CHECK(pending["seq"] == seq);
      CHECK(pending["kind"] == "entry");
      CHECK(pending["outcome"] == "pending");
      log.finish(seq, i % 2 ? "ok" : "blocked", "why");
    }
    CHECK(log.to_json(1)["file"] == file.string());
  }
  std::ifstream in(file);
  int lines = 0;
  for (std::string line; std::getline(in, line); ++lines) {
    const auto entry = nlohmann::json::parse(line);
    const int n = lines / 2;
    CHECK(entry["seq"] == n + 1);
    CHECK(entry["message_id"] == "m" + std::to_string(n));
    CHECK(entry["kind"] == (lines % 2 ? "outcome" : "entry"));
    CHECK(entry["outcome"] == (lines % 2 ? (n % 2 ? "ok" : "blocked") : "pending"));
  }
  CHECK(lines == 8);
  std::filesystem::remove(file);
  std::filesystem::remove(AuditLog::stops_file_for(file));
}

TEST_CASE("an audit file that cannot be opened is a clear startup error") {
  AuditLog log;
  CHECK_THROWS_WITH_AS(log.persist_to("/nonexistent-dir/rcand/audit.jsonl"), doctest::Contains("runtime.audit_file"),
                       std::runtime_error);
}

namespace {

struct AuditScratch {
  std::filesystem::path dir;
  AuditScratch() {
    std::string pattern = (std::filesystem::temp_directory_path() / "rcand-audit-unit-XXXXXX").string();
    REQUIRE(::mkdtemp(pattern.data()) != nullptr);
    dir = pattern;
  }
  ~AuditScratch() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
};

std::vector<nlohmann::json> audit_unit_lines(const std::filesystem::path& file) {
  std::vector<nlohmann::json> lines;
  std::ifstream in(file);
  for (std::string line; std::getline(in, line);) lines.push_back(nlohmann::json::parse(line));
  return lines;
}

}  // namespace

TEST_CASE("every text field is bounded as it is recorded: length, UTF-8, control characters") {
  AuditScratch scratch;
  const auto file = scratch.dir / "audit.jsonl";
  AuditLog log;
  log.persist_to(file);
  const std::string huge(1 << 20, 'x');
  const auto seq =
      log.record({0, huge, huge, "id\n\x1b[31m" + huge, "POST /api/nav/waypoint " + huge, 1, "pending", huge, nullptr});
  log.finish(seq, "error", "bad type '" + huge + "' \xff");
  const auto entry = log.to_json(1)["entries"][0];
  CHECK(entry["principal"].get<std::string>().size() <= AuditLog::kFieldLimit);
  CHECK(entry["ruri"].get<std::string>().size() <= AuditLog::kFieldLimit);
  CHECK(entry["message_id"].get<std::string>().size() <= AuditLog::kFieldLimit);
  CHECK(entry["message_id"].get<std::string>().rfind("id??[31m", 0) == 0);  // control characters replaced
  CHECK(entry["event"].get<std::string>().size() <= AuditLog::kEventLimit);
  CHECK(entry["event"].get<std::string>().rfind("POST /api/nav/waypoint xxx", 0) == 0);
  CHECK(entry["event"].get<std::string>().find("bytes)") != std::string::npos);  // says how much was cut
  CHECK(entry["detail"].get<std::string>().size() <= AuditLog::kDetailLimit);
  for (const auto& line : audit_unit_lines(file)) CHECK(line.dump().size() < 4000);
}

TEST_CASE("the file rotates by size and keeps `keep` rotated files") {
  AuditScratch scratch;
  const auto file = scratch.dir / "audit.jsonl";
  {
    AuditLog log;
    log.persist_to(file, 4096, 2);
    for (int i = 0; i < 60; ++i)
      log.finish(log.record({0, "p", "r", "m" + std::to_string(i), "POST /x", 1, "pending", {}, nullptr}), "ok");
  }
  const std::filesystem::path one = file.string() + ".1", two = file.string() + ".2";
  CHECK(std::filesystem::exists(one));
  CHECK(std::filesystem::exists(two));
  CHECK_FALSE(std::filesystem::exists(file.string() + ".3"));
  std::uint64_t expected = 0;
  for (const auto& part : {two, one, file}) {
    CHECK(std::filesystem::file_size(part) <= 4096);
    for (const auto& line : audit_unit_lines(part)) {
      const auto seq = line["seq"].get<std::uint64_t>();
      if (expected != 0) CHECK(seq >= expected);  // oldest file first, nothing out of order across files
      expected = seq;
    }
  }
  CHECK(expected == 60);
}

TEST_CASE("the sequence continues from the file, also right after a rotation, and skips a line cut by a crash") {
  AuditScratch scratch;
  const auto file = scratch.dir / "audit.jsonl";
  {
    AuditLog log;
    log.persist_to(file);
    for (int i = 0; i < 5; ++i) log.record({0, "p", "r", "m", "POST /x", 1, "pending", {}, nullptr});  // never finished: a crash
  }
  std::ofstream(file, std::ios::app) << R"({"seq":99,"kind":"entr)";  // the half-written line of a kill -9
  {
    AuditLog log;
    log.persist_to(file);
    CHECK(log.record({0, "p", "r", "m", "POST /x", 1, "pending", {}, nullptr}) == 6);
    CHECK(log.total() == 1);  // this run's entries
  }
  std::filesystem::rename(file, file.string() + ".1");  // as if it had just rotated
  AuditLog log;
  log.persist_to(file);
  CHECK(log.record({0, "p", "r", "m", "POST /x", 1, "pending", {}, nullptr}) == 7);
}

// Issue 28 #7: a GUEST's stop flood (2,000 a second) pushed a USER's move out of memory and out of the files.
TEST_CASE("stops repeated while latched are one entry: count, last time and message id, before the latch") {
  AuditLog log;
  const auto first = log.begin_stop("guest", "m-0", "POST /api/stop", false);
  REQUIRE(first != 0);
  for (int i = 1; i <= 5000; ++i) CHECK(log.begin_stop("guest", "m-" + std::to_string(i), "POST /api/stop", true) == 0);
  log.finish(first, "ok");
  log.finish(0, "ok");  // what the stop handler does for a repeat: nothing
  const auto doc = log.to_json(10);
  REQUIRE(doc["entries"].size() == 1);
  const auto entry = doc["entries"][0];
  CHECK(entry["seq"] == first);
  CHECK(entry["count"] == 5001);
  CHECK(entry["message_id"] == "m-0");
  CHECK(entry["last_message_id"] == "m-5000");
  CHECK(entry["last_ms"].get<std::int64_t>() >= entry["timestamp_ms"].get<std::int64_t>());
  CHECK(entry["outcome"] == "ok");
  CHECK(doc["total"] == 1);
  CHECK(doc["dropped"] == 0);
  // Another principal's stop, or the same principal's other stop event, is an entry of its own; so is a stop after
  // the e-stop was cleared.
  CHECK(log.begin_stop("user", "u-1", "POST /api/stop", true) != 0);
  CHECK(log.begin_stop("guest", "p-1", "estop requested by plugin nav", true) != 0);
  log.end_repeats();
  CHECK(log.begin_stop("guest", "m-after-clear", "POST /api/stop", true) != 0);
  CHECK(log.to_json(1)["entries"][0]["message_id"] == "m-after-clear");
  CHECK_FALSE(log.to_json(1)["entries"][0].contains("count"));
}

TEST_CASE("stops never displace a command, a clear or a config change: their own ring, merged newest first") {
  AuditLog log(4, 3);
  log.finish(log.begin("user", "move-1", "POST /api/action move"), "ok");
  log.finish(log.begin("owner", "clear-1", "POST /api/estop/clear"), "ok");
  log.finish(log.begin("SIGHUP", "reload-1", "config reload"), "ok");
  // Stops that are no repeats (the robot is never latched here): each an entry, 10,000 of them.
  for (int i = 0; i < 10000; ++i) log.finish(log.begin_stop("guest", "s-" + std::to_string(i), "POST /api/stop", false), "ok");
  log.finish(log.begin("user", "move-2", "POST /api/action move"), "blocked", "e-stop active");
  const auto doc = log.to_json(100);
  std::vector<std::string> ids;
  for (const auto& entry : doc["entries"]) ids.push_back(entry["message_id"]);
  CHECK(ids == std::vector<std::string>{"move-2", "s-9999", "s-9998", "s-9997", "reload-1", "clear-1", "move-1"});
  CHECK(doc["dropped"] == 9997);
  CHECK(doc["dropped_stops"] == 9997);
  std::uint64_t previous = UINT64_MAX;
  for (const auto& entry : doc["entries"]) {  // newest first, by seq
    CHECK(entry["seq"].get<std::uint64_t>() < previous);
    previous = entry["seq"].get<std::uint64_t>();
  }
  CHECK(log.to_json(2)["entries"].size() == 2);
}

TEST_CASE("with a file, stops go to a file of their own: a flood rotates only that one, repeats write a line a second") {
  AuditScratch scratch;
  const auto file = scratch.dir / "audit.jsonl";
  const auto stops = AuditLog::stops_file_for(file);
  CHECK(stops == scratch.dir / "audit.stops.jsonl");
  std::uint64_t move = 0, first_stop = 0;
  {
    AuditLog log;
    log.persist_to(file, 4096, 1);
    move = log.begin("user", "move-1", "POST /api/action move");
    log.finish(move, "ok");
    for (int i = 0; i < 500; ++i)
      log.finish(log.begin_stop("guest", "s-" + std::to_string(i), "POST /api/swarm/x/stop", false), "error");
    first_stop = log.begin_stop("guest", "latch", "POST /api/stop", false);
    log.finish(first_stop, "ok");
    for (int i = 0; i < 100000; ++i) log.begin_stop("guest", "r-" + std::to_string(i), "POST /api/stop", true);
    CHECK(log.to_json(1)["stops_file"] == stops.string());
  }  // exit: the final count is written
  // The move is still in the main file, whole; the stops file rotated.
  const auto main_lines = audit_unit_lines(file);
  REQUIRE(main_lines.size() == 2);
  CHECK(main_lines[0]["seq"] == move);
  CHECK(main_lines[1]["outcome"] == "ok");
  CHECK(std::filesystem::exists(stops.string() + ".1"));
  CHECK_FALSE(std::filesystem::exists(file.string() + ".1"));
  // 100,000 repeats within a second or two: a handful of repeat lines, the last with the whole count.
  int repeat_lines = 0;
  nlohmann::json last_repeat;
  for (const auto& line : audit_unit_lines(stops)) {
    if (line["kind"] != "repeat") continue;
    CHECK(line["seq"] == first_stop);
    ++repeat_lines;
    last_repeat = line;
  }
  CHECK(repeat_lines >= 2);   // the first repeat, and the final count at exit
  CHECK(repeat_lines <= 10);  // never one per repeat
  CHECK(last_repeat["count"] == 100001);
  CHECK(last_repeat["last_message_id"] == "r-99999");
  // The sequence continues after the highest seq of either file.
  AuditLog again;
  again.persist_to(file, 4096, 1);
  CHECK(again.begin("user", "after", "POST /api/action move") == first_stop + 1);
}

TEST_CASE("LogRateLimiter: N lines a second per source, then the count of suppressed ones on the next line") {
  LogRateLimiter limiter(3, 4);
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < 3; ++i) CHECK(limiter.admit("alice", t0).log);
  for (int i = 0; i < 10; ++i) CHECK_FALSE(limiter.admit("alice", t0).log);
  CHECK(limiter.admit("bob", t0).log);  // another source has its own budget
  const auto next = limiter.admit("alice", t0 + std::chrono::milliseconds(1001));
  CHECK(next.log);
  CHECK(next.suppressed == 10);
  CHECK(limiter.admit("alice", t0 + std::chrono::milliseconds(1002)).suppressed == 0);
  // Many sources: the table stays bounded (new ones share one budget when it is full).
  int logged = 0;
  for (int i = 0; i < 1000; ++i) logged += limiter.admit("source-" + std::to_string(i), t0 + std::chrono::milliseconds(1003)).log;
  CHECK(logged <= 3 + 3);
}
