// The token buckets behind 429 (docs/protocol.md §6.4), on an explicit clock: no sleeping.
#include <doctest/doctest.h>

#include <string>

#include "libs/base/bounded_text.hpp"
#include "libs/base/json_body.hpp"
#include "libs/base/rate_limiter.hpp"

using namespace rcand;

TEST_CASE("rate limiter: a burst of per_s * burst_s, then one request per 1/per_s, each key on its own") {
  RateLimiter limiter({10, 2});  // 10/s, bursts of 20
  std::int64_t now = 1'000'000;
  for (int i = 0; i < 20; ++i) CHECK_FALSE(limiter.admit("alice", now).has_value());
  const auto wait = limiter.admit("alice", now);
  REQUIRE(wait.has_value());
  CHECK(wait->count() == 100);                         // one request's worth of refill at 10/s
  CHECK_FALSE(limiter.admit("bob", now).has_value());  // another principal is not affected
  now += 100'000;
  CHECK_FALSE(limiter.admit("alice", now).has_value());
  CHECK(limiter.admit("alice", now).has_value());
  now += 10'000'000;  // a long pause refills the bucket, never beyond the burst
  for (int i = 0; i < 20; ++i) CHECK_FALSE(limiter.admit("alice", now).has_value());
  CHECK(limiter.admit("alice", now).has_value());
}

TEST_CASE("rate limiter: 0 per second is unlimited") {
  RateLimiter limiter({0, 2});
  for (int i = 0; i < 10000; ++i) REQUIRE_FALSE(limiter.admit("x", 0).has_value());
  CHECK(limiter.keys() == 0);
}

TEST_CASE("rate limiter: the table stays bounded while keys cycle, and a busy key keeps its bucket") {
  RateLimiter limiter({1, 1}, 64);
  for (int i = 0; i < 1; ++i) CHECK_FALSE(limiter.admit("busy", 0).has_value());
  CHECK(limiter.admit("busy", 0).has_value());
  for (int i = 0; i < 10000; ++i) limiter.admit("attacker-" + std::to_string(i), 1000 + i);
  CHECK(limiter.keys() <= 64);
}

TEST_CASE("bounded text: short and printable, valid UTF-8, never cut inside a character") {
  CHECK(bounded_text("plain") == "plain");
  CHECK(bounded_text("a\nb\x01" "c") == "a?b?c");
  CHECK(bounded_text("bad \xff\xfe utf8") == "bad ?? utf8");
  const std::string long_text(1 << 20, 'x');
  const std::string cut = bounded_text(long_text);
  CHECK(cut.size() <= kQuotedTextLimit);
  CHECK(cut.find("bytes)") != std::string::npos);
  std::string accents;
  for (int i = 0; i < 150; ++i) accents += "\xc3\xa9";  // é, two bytes each
  const std::string reason = bounded_text(accents);
  CHECK(reason.size() <= kQuotedTextLimit);
  CHECK(bounded_text(reason, 1000) == reason);  // what came out is valid UTF-8: a second pass changes nothing
}

TEST_CASE("json bodies: the error names the byte, never quotes the input or the library") {
  const auto parsed = parse_json_body("{\"secret-looking\": nope}");
  CHECK(parsed.error.find("byte") != std::string::npos);
  CHECK(parsed.error.find("nope") == std::string::npos);
  CHECK(parsed.error.find("json.exception") == std::string::npos);
}
