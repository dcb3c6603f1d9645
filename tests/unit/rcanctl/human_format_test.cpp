// Values as people read them in rcanctl's tables (issue 29 item 5: `nav status` printed 1.6e-17, times as raw
// milliseconds).
#include <doctest/doctest.h>

#include <cstdlib>
#include <ctime>
#include <string>

#include "human_format.hpp"

using nlohmann::json;
using rcand::rcanctl::human_number;
using rcand::rcanctl::human_text;
using rcand::rcanctl::human_time;
using rcand::rcanctl::local_time;

namespace {

// Runs with the process's time zone set to a POSIX TZ string (no tz database needed), then restores it.
struct ZoneFixture {
  std::string before;
  bool had = false;
  explicit ZoneFixture(const char* zone) {
    if (const char* tz = std::getenv("TZ")) {
      had = true;
      before = tz;
    }
    ::setenv("TZ", zone, 1);
    ::tzset();
  }
  ~ZoneFixture() {
    if (had) ::setenv("TZ", before.c_str(), 1);
    else ::unsetenv("TZ");
    ::tzset();
  }
};

}  // namespace

TEST_CASE("numbers print as people write them, never in exponent form") {
  CHECK(human_number(1.6e-17) == "0");
  CHECK(human_number(-1.6e-17) == "0");  // not "-0"
  CHECK(human_number(0.25000000000000006) == "0.25");
  CHECK(human_number(2.0) == "2");
  CHECK(human_number(-3.14159) == "-3.142");
  CHECK(human_number(1234567.5) == "1234567.5");
  CHECK(human_number(0.5, 0) == "0");  // rounds half to even, like printf
  CHECK(human_text(json(1.6e-17)) == "0");
  CHECK(human_text(json(42)) == "42");  // integers exactly
  CHECK(human_text(json(true)) == "yes");
  CHECK(human_text(json()) == "-");
  CHECK(human_text(json("idle")) == "idle");
}

TEST_CASE("times print in the local zone as ISO 8601 with the offset") {
  constexpr std::int64_t kMs = 1795827723456;  // 2026-11-28T01:02:03.456Z
  {
    const ZoneFixture utc("UTC0");
    CHECK(local_time(kMs) == "2026-11-28T01:02:03.456+00:00");
  }
  {
    const ZoneFixture east("XYZ-1");  // POSIX: one hour east of UTC
    CHECK(local_time(kMs) == "2026-11-28T02:02:03.456+01:00");
    CHECK(human_time(json(kMs)) == "2026-11-28T02:02:03.456+01:00");
  }
  {
    const ZoneFixture west("ABC+5:30");
    CHECK(local_time(kMs) == "2026-11-27T19:32:03.456-05:30");
  }
  CHECK(human_time(json()) == "-");
  CHECK(human_time(json("soon")) == "-");
}
