// The audit log never loses an entry silently: rotation out of memory is counted, and the file keeps every one.
#include <doctest/doctest.h>

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <chrono>
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
}

TEST_CASE("an audit file that cannot be opened is a clear startup error") {
  AuditLog log;
  CHECK_THROWS_WITH_AS(log.persist_to("/nonexistent-dir/rcand/audit.jsonl"), doctest::Contains("runtime.audit_file"), std::runtime_error);
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
