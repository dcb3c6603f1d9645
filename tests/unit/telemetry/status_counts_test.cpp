// A route's answers per status code: codes in the order first seen, out-of-range statuses as 500, codes past the
// slots as "other" (0), and no count lost when threads claim slots at once.
#include <doctest/doctest.h>

#include <map>
#include <thread>
#include <utility>
#include <vector>

#include "services/telemetry/status_counts.hpp"

using rcand::services::telemetry::StatusCounts;

namespace {
std::vector<std::pair<int, std::uint64_t>> seen(const StatusCounts& counts) {
  std::vector<std::pair<int, std::uint64_t>> out;
  counts.for_each([&](int code, std::uint64_t n) { out.emplace_back(code, n); });
  return out;
}
}  // namespace

TEST_CASE("status counts: per code, in the order first seen") {
  StatusCounts counts;
  CHECK(seen(counts).empty());
  counts.add(200);
  counts.add(404);
  counts.add(200);
  counts.add(42);   // not an HTTP status: what the client got is a 500
  counts.add(700);  // likewise
  CHECK(seen(counts) == std::vector<std::pair<int, std::uint64_t>>{{200, 2}, {404, 1}, {500, 2}});
}

TEST_CASE("status counts: codes past the slots are counted as other") {
  StatusCounts counts;
  for (std::size_t i = 0; i < StatusCounts::kSlots + 3; ++i) counts.add(400 + static_cast<int>(i));
  counts.add(400);
  const auto all = seen(counts);
  REQUIRE(all.size() == StatusCounts::kSlots + 1);
  CHECK(all.front() == std::pair<int, std::uint64_t>{400, 2});
  CHECK(all.back() == std::pair<int, std::uint64_t>{0, 3});
}

TEST_CASE("status counts: threads claiming slots at once lose no count and share a code's slot") {
  StatusCounts counts;
  constexpr int kThreads = 4, kEach = 20000;
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&counts, t] {
      for (int i = 0; i < kEach; ++i) counts.add(i % 2 == 0 ? 200 : 500 + t % 2);
    });
  for (auto& thread : threads) thread.join();
  std::map<int, std::uint64_t> by_code;
  for (const auto& [code, n] : seen(counts)) {
    CHECK(by_code.count(code) == 0);  // one slot per code
    by_code[code] = n;
  }
  CHECK(by_code == std::map<int, std::uint64_t>{{200, kThreads * kEach / 2}, {500, kEach}, {501, kEach}});
}
