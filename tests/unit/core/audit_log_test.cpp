// The audit log never loses an entry silently: rotation out of memory is counted, and the file keeps every one.
#include <doctest/doctest.h>

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "rcand/kernel/core/audit_log.hpp"

using namespace rcand::kernel;

TEST_CASE("entries rotated out of the in-memory ring are counted as dropped") {
  AuditLog log(3);
  for (int i = 0; i < 5; ++i) log.finish(log.record({0, "p", "r", "m" + std::to_string(i), "POST /x", 1, "pending", {}}), "ok");
  const auto doc = log.to_json(100);
  CHECK(doc["entries"].size() == 3);
  CHECK(doc["total"] == 5);
  CHECK(doc["dropped"] == 2);
  CHECK(log.dropped() == 2);
}

TEST_CASE("with a file, every finished entry is appended as one JSON line, rotated ones included") {
  const auto file = std::filesystem::temp_directory_path() / ("rcand-audit-test-" + std::to_string(::getpid()) + ".jsonl");
  std::filesystem::remove(file);
  {
    AuditLog log(2);
    log.persist_to(file);
    for (int i = 0; i < 4; ++i)
      log.finish(log.record({0, "p", "r", "m" + std::to_string(i), "POST /x", 1, "pending", {}}), i % 2 ? "ok" : "blocked", "why");
    CHECK(log.to_json(1)["file"] == file.string());
  }
  std::ifstream in(file);
  int lines = 0;
  for (std::string line; std::getline(in, line); ++lines) {
    const auto entry = nlohmann::json::parse(line);
    CHECK(entry["message_id"] == "m" + std::to_string(lines));
    CHECK(entry["outcome"] == (lines % 2 ? "ok" : "blocked"));
  }
  CHECK(lines == 4);
  std::filesystem::remove(file);
}

TEST_CASE("an audit file that cannot be opened is a clear startup error") {
  AuditLog log;
  CHECK_THROWS_WITH_AS(log.persist_to("/nonexistent-dir/rcand/audit.jsonl"), doctest::Contains("runtime.audit_file"), std::runtime_error);
}
