// Issue 13, the Api's part: rate limits with 429 + Retry-After that never touch the e-stop paths, the scope of
// POST /api/command checked before anything is revealed, ?limit= refused out of range, no file paths for a guest,
// and no library internals or cut characters in what the robot says back.
#include <doctest/doctest.h>

#include <chrono>
#include <string>

#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

nlohmann::json limited_config(double per_principal, double per_address) {
  auto config = sim_config();
  config["runtime"]["rate_limit"] = {{"per_principal_per_s", per_principal}, {"per_address_per_s", per_address}, {"burst_s", 1}};
  return config;
}

}  // namespace

TEST_CASE("rate limit per principal: 429 with Retry-After once the burst is spent; stops and other principals unaffected") {
  RcandProcess rcand(limited_config(4, 0));  // bursts of 4 per principal, no address limit
  int refused = 0, admitted = 0;
  for (int i = 0; i < 12; ++i) {
    const auto answer = rcand.request("GET", "/api/status", "user-token");
    if (answer.status == 429) {
      ++refused;
      const auto body = json::parse(answer.body);
      CHECK(body["code"] == "RATE_LIMITED");
      CHECK(body["status"] == 429);
      CHECK(body["retry_after_s"].get<int>() >= 1);
      CHECK(answer.headers.count("retry-after") == 1);
    } else {
      CHECK(answer.status == 200);
      ++admitted;
    }
  }
  CHECK(refused >= 6);   // 4 in the burst, plus at most a few refilled while the loop ran
  CHECK(admitted >= 4);
  // The e-stop paths are never limited, for the same principal, however many.
  for (int i = 0; i < 10; ++i) {
    CHECK(rcand.request("POST", "/api/stop", "user-token").status == 200);
    CHECK(rcand.request("GET", "/api/estop", "user-token").status == 200);
  }
  // Another principal has a bucket of its own.
  CHECK(rcand.request("GET", "/api/status", "guest-token").status == 200);
}

TEST_CASE("rate limit per address: unauthenticated floods get 429, the stop still gets through") {
  RcandProcess rcand(limited_config(0, 5));
  int refused = 0;
  for (int i = 0; i < 20; ++i) {
    const auto answer = rcand.request("GET", i % 2 ? "/health" : "/api/status", i % 3 ? "" : "wrong-token");
    if (answer.status == 429) ++refused;
  }
  CHECK(refused >= 10);
  int status = 0;
  const auto stopped = rcand.json("POST", "/api/stop", "guest-token", R"({"reason":"flooded"})", &status);
  CHECK(status == 200);
  CHECK(stopped["estopped"] == true);
}

TEST_CASE("refusals are logged at most 5 lines a second per client address, then how many were left out") {
  RcandProcess rcand(sim_config());
  for (int i = 0; i < 300; ++i) CHECK(rcand.request("GET", "/api/status", "not-a-token").status == 401);
  // A line after the flood carries the count of the lines held back (the next window's first refusal).
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (count_of(rcand.stderr_text(), "more refusals for 127.0.0.1 not logged") == 0 && std::chrono::steady_clock::now() < give_up)
    rcand.request("GET", "/api/status", "not-a-token");
  const std::string log = rcand.stderr_text();
  const auto logged = count_of(log, "GET /api/status from 127.0.0.1:");
  MESSAGE(logged << " refusal lines logged");
  CHECK(logged >= 5);
  CHECK(logged < 100);  // 300+ refusals in a few seconds: 5 a second, not one each
  CHECK(count_of(log, "more refusals for 127.0.0.1 not logged") >= 1);
  CHECK(log.find("not-a-token") == std::string::npos);
}

TEST_CASE("POST /api/command without control is 403 before the capability is looked up") {
  RcandProcess rcand(sim_config());  // chat is not declared
  int status = 0;
  auto body = rcand.json("POST", "/api/command", "guest-token", R"({"instruction":"hi"})", &status);
  CHECK(status == 403);
  CHECK(body["code"] == "INSUFFICIENT_PRIVILEGES");
  CHECK(body["required_scope"] == "control");
  body = rcand.json("POST", "/api/command", "user-token", R"({"instruction":"hi"})", &status);
  CHECK(status == 404);
  CHECK(body["code"] == "CAPABILITY_NOT_FOUND");
  rcand.json("GET", "/api/nav/status", "guest-token", "", &status);
  CHECK(status == 404);  // reading an undeclared capability needs only status
}

TEST_CASE("GET /api/audit?limit= outside [1, 10000] is refused, not clamped") {
  RcandProcess rcand(sim_config());
  int status = 0;
  for (const char* limit : {"10001", "0", "99999999999999999999", "-1", "5x"}) {
    CAPTURE(limit);
    auto body = rcand.json("GET", std::string("/api/audit?limit=") + limit, "owner-token", "", &status);
    CHECK(status == 400);
    CHECK(body["field"] == "limit");
  }
  rcand.json("GET", "/api/audit?limit=10000", "owner-token", "", &status);
  CHECK(status == 200);
}

TEST_CASE("GET /api/plugins shows a guest no file paths; an owner sees them") {
  RcandProcess rcand(sim_config());
  const auto guest = rcand.request("GET", "/api/plugins", "guest-token");
  REQUIRE(guest.status == 200);
  CHECK(guest.body.find(plugin_dir().string()) == std::string::npos);
  CHECK(guest.body.find("\"manifest\"") == std::string::npos);
  CHECK(json::parse(guest.body)["plugins"].size() >= 2);
  const auto owner = rcand.request("GET", "/api/plugins", "owner-token");
  CHECK(owner.body.find("\"manifest\"") != std::string::npos);
}

TEST_CASE("the stop reason is bounded without cutting a character; a bad body's error quotes no internals") {
  RcandProcess rcand(sim_config());
  std::string reason = "x";  // then 300 bytes of 'é': a cut at byte 200 would split one
  for (int i = 0; i < 150; ++i) reason += "\xc3\xa9";
  int status = 0;
  rcand.json("POST", "/api/stop", "guest-token", json{{"reason", reason}}.dump(), &status);
  CHECK(status == 200);
  const auto estop = rcand.json("GET", "/api/estop", "guest-token");
  const std::string stored = estop["reason"];
  CHECK(stored.size() <= 200);
  CHECK(stored.rfind("x\xc3\xa9", 0) == 0);
  CHECK(stored.find("\xef\xbf\xbd") == std::string::npos);  // no U+FFFD: no character was cut in half
  CHECK_NOTHROW((void)json(stored).dump());                 // valid UTF-8 (dump throws otherwise)

  const auto bad = rcand.json("POST", "/api/action", "user-token", R"({"type": nope})", &status);
  CHECK(status == 400);
  const std::string error = bad["error"];
  CHECK(error.find("json.exception") == std::string::npos);
  CHECK(error.find("nope") == std::string::npos);
  CHECK(error.find("byte") != std::string::npos);

  const auto unknown = rcand.json("POST", "/api/action", "user-token", json{{"type", std::string((1 << 20) - 100, 't')}}.dump(), &status);
  CHECK(status == 400);
  CHECK(unknown.dump().size() < 2000);  // the 1 MiB type is not echoed back
}
