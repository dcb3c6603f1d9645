// Fault drill and feature test: config reload on SIGHUP. The config file replaced by garbage is logged with
// file:line:column and rcand keeps running on the old config (old tokens work, stops answer within 500 ms); a valid
// file then applies what can change while serving (tokens, log level) and names the keys that need a restart. Both
// reloads are in the audit log, and no request's entry is lost.
#include <doctest/doctest.h>
#include <signal.h>

#include <string>

#include "fault_drill.hpp"
#include "libs/rcan/crypto.hpp"
#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// Sends SIGHUP and waits for the reload's log line (the n-th one).
void reload(const RcandProcess& rcand, std::size_t nth) {
  REQUIRE(::kill(rcand.pid(), SIGHUP) == 0);
  REQUIRE(drill::eventually([&] { return count(rcand.stderr_text(), "config reload from") >= nth; }));
}

json reload_entry(const RcandProcess& rcand, const std::string& token, std::size_t nth_newest = 0) {
  std::size_t seen = 0;
  const json audit = rcand.json("GET", "/api/audit?limit=10000", token);  // kept alive for the loop
  for (const auto& entry : audit["entries"])
    if (entry.value("event", "") == "config reload" && seen++ == nth_newest) return entry;
  return json::object();
}

}  // namespace

TEST_CASE("fault drill: SIGHUP with the config replaced by garbage keeps the old config; a valid one applies") {
  const auto config = sim_config();
  RcandProcess rcand(config);
  const auto file = rcand.dir().path() / "robot.rcan.yaml";
  std::vector<std::string> audited;
  auto stop = [&](const std::string& name) {
    audited.push_back("reload-" + name);
    drill::stop_within_limit(rcand, audited.back());
  };
  stop("before");

  for (const std::string& garbage :
       {std::string("metadata: [unclosed\n  robot_name: {{{\n"), std::string("\x00\xff\xfe\x01garbage", 11),
        std::string("rcan_version: 1.3\nmetadata: 42\n")}) {
    rcand.dir().write("robot.rcan.yaml", garbage);
    const auto reloads = count(rcand.stderr_text(), "config reload from");
    reload(rcand, reloads + 1);
    const auto log = rcand.stderr_text();
    CHECK(log.find(file.string() + ":") != std::string::npos);  // file:line:column of the error
    CHECK(log.find("invalid; still running on the previous config") != std::string::npos);
    stop("garbage-" + std::to_string(reloads));
    int status = 0;
    rcand.json("GET", "/api/status", "owner-token", "", &status);
    CHECK(status == 200);  // the old tokens still work
    const auto entry = reload_entry(rcand, "owner-token");
    CHECK(entry.value("outcome", "") == "error");
  }

  // A valid file: a new owner token replaces the old ones, the log level changes, a driver changes (restart needed).
  auto next = config;
  next["runtime"]["auth"]["tokens"] =
      json::array({{{"principal", "fresh-owner"}, {"role", "owner"}, {"sha256", rcand::sha256_hex("fresh-token")}},
                   {{"principal", "guest-principal"}, {"role", "guest"}, {"sha256", rcand::sha256_hex("guest-token")}}});
  next["runtime"]["logging"]["level"] = "warn";
  next["drivers"][0]["id"] = "drive9";
  rcand.dir().write("robot.rcan.yaml", next.dump(2));
  reload(rcand, count(rcand.stderr_text(), "config reload from") + 1);
  int status = 0;
  rcand.json("GET", "/api/status", "owner-token", "", &status);
  CHECK(status == 401);  // the old owner token is gone
  rcand.json("GET", "/api/status", "fresh-token", "", &status);
  CHECK(status == 200);
  const auto entry = reload_entry(rcand, "fresh-token");
  CHECK(entry.value("outcome", "") == "ok");
  const std::string detail = entry.value("detail", "");
  CHECK(detail.find("applied: runtime.auth.tokens, runtime.logging.level") != std::string::npos);
  CHECK(detail.find("needs a restart: drivers") != std::string::npos);
  CHECK(reload_entry(rcand, "fresh-token", 1).value("outcome", "") == "error");  // the garbage ones are there too
  audited.push_back("reload-after");
  CHECK(drill::tagged(rcand, "POST", "/api/stop", "guest-token", "", audited.back()).took < drill::kStopLimit);
  // The first stop latched; every later one, across the reloads, is counted into its entry (same guest principal).
  drill::check_stops_audited(rcand, audited, "fresh-token");
}
