// Fault-drill checks (header-only), shared by tests/integration/fault_drill_*_test.cpp: every drill makes its
// requests with an X-Message-Id of its own, asserts POST /api/stop answers within the docs/protocol.md §6 limit, and finally
// that the audit log holds every audited request it made.
#pragma once

#include <doctest/doctest.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "eventually.hpp"
#include "rcand_process.hpp"

namespace rcand::test::drill {

inline constexpr auto kStopLimit = std::chrono::milliseconds(500);  // docs/protocol.md §6: MUST answer within 500 ms

struct Answer {
  int status = 0;
  nlohmann::json body;
  std::chrono::milliseconds took{0};
};

// One request on a fresh connection carrying "X-Message-Id: <id>"; the body parsed as JSON (null when not JSON).
inline Answer tagged(const RcandProcess& rcand, const std::string& method, const std::string& target, const std::string& token,
                     const std::string& body, const std::string& id) {
  const auto start = std::chrono::steady_clock::now();
  const auto response = rcand.request(method, target, token, body, {{"X-Message-Id", id}});
  Answer answer;
  answer.took = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - start);
  answer.status = response.status;
  answer.body = nlohmann::json::parse(response.body, nullptr, false);
  return answer;
}

// POST /api/stop (as the guest: any valid token may stop), checked against the limit; returns the answer.
inline Answer stop_within_limit(const RcandProcess& rcand, const std::string& id) {
  const auto answer = tagged(rcand, "POST", "/api/stop", "guest-token", "", id);
  CHECK(answer.status == 200);
  CHECK(answer.took < kStopLimit);
  CHECK(answer.body.value("estopped", false));
  return answer;
}

// The message ids of `ids` that GET /api/audit does not hold. A stop repeated while latched is counted into the entry
// it repeats (docs/protocol.md §6.3): the latest repeat's id is that entry's last_message_id.
inline std::vector<std::string> missing_from_audit(const RcandProcess& rcand, const std::vector<std::string>& ids) {
  const auto audit = rcand.json("GET", "/api/audit?limit=10000", "owner-token");
  std::set<std::string> present;
  for (const auto& entry : audit.value("entries", nlohmann::json::array())) {
    present.insert(entry.value("message_id", ""));
    present.insert(entry.value("last_message_id", ""));
  }
  std::vector<std::string> missing;
  for (const auto& id : ids)
    if (!present.contains(id)) missing.push_back(id);
  return missing;
}

inline void check_audit_complete(const RcandProcess& rcand, const std::vector<std::string>& ids) {
  const auto missing = missing_from_audit(rcand, ids);
  CHECK_MESSAGE(missing.empty(), "audit entries lost: " << nlohmann::json(missing).dump());
  const auto audit = rcand.json("GET", "/api/audit?limit=1", "owner-token");
  CHECK(audit.value("dropped", -1) == 0);
}

// Stops `ids`, sent in this order by one principal while the robot stayed latched: the first has its own audit entry,
// every later one is counted into it (docs/protocol.md §6.3: a stop repeated while latched is coalesced), so that
// entry's count is their number and its last_message_id the last; nothing rotated out of memory.
inline void check_stops_audited(const RcandProcess& rcand, const std::vector<std::string>& ids,
                                const std::string& token = "owner-token") {
  REQUIRE(!ids.empty());
  const auto audit = rcand.json("GET", "/api/audit?limit=10000", token);
  nlohmann::json found;
  for (const auto& entry : audit.value("entries", nlohmann::json::array()))
    if (entry.value("message_id", "") == ids.front()) found = entry;
  INFO("audit: " << audit.dump());
  REQUIRE_MESSAGE(found.is_object(), "audit entry lost: " << ids.front());
  CHECK(found.value("count", std::uint64_t{1}) == ids.size());
  if (ids.size() > 1) CHECK(found.value("last_message_id", "") == ids.back());
  CHECK(audit.value("dropped", -1) == 0);
}

// Raises this process's open-file limit (rcand processes it starts inherit it) to at least `wanted`, if the hard
// limit allows; returns the soft limit in force.
inline rlim_t raise_open_files(rlim_t wanted) {
  rlimit limit{};
  getrlimit(RLIMIT_NOFILE, &limit);
  if (limit.rlim_cur < wanted) {
    limit.rlim_cur = std::min(wanted, limit.rlim_max);
    setrlimit(RLIMIT_NOFILE, &limit);
    getrlimit(RLIMIT_NOFILE, &limit);
  }
  return limit.rlim_cur;
}

// Sets this process's soft open-file limit (processes it starts inherit it); the hard limit stays.
inline void set_open_files_soft(rlim_t soft) {
  rlimit limit{};
  getrlimit(RLIMIT_NOFILE, &limit);
  limit.rlim_cur = std::min(soft, limit.rlim_max);
  setrlimit(RLIMIT_NOFILE, &limit);
}

using rcand::test::eventually;

}  // namespace rcand::test::drill
