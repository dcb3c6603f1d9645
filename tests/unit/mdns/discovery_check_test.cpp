// rcanctl discover's check: the registry's own TXT and DISCOVER agree; every kind of drift is named.
#include <doctest/doctest.h>

#include "discover_command.hpp"
#include "kernel/registry/capability_registry.hpp"

using namespace rcand;
using nlohmann::json;

namespace {

kernel::Advertisement advertised(const std::string& status, std::uint16_t port) {
  kernel::CapabilityPlan plan;
  plan.names = {"status", "teleop", "com.acme.gripper"};
  kernel::CapabilityRegistry registry({"rcan://rcand.sim-rover.5f3c2a1b", "rover", "sim-rover"}, plan);
  return registry.advertise(status, port);
}

bool names(const std::vector<std::string>& problems, const std::string& what) {
  for (const auto& problem : problems)
    if (problem.find(what) != std::string::npos) return true;
  return false;
}

}  // namespace

TEST_CASE("discover: the one registry function's TXT and DISCOVER agree; drift in any key is reported") {
  const auto ad = advertised("idle", 8000);
  CHECK(rcanctl::discovery_disagreements(ad.txt, 8000, ad.discover).empty());

  auto txt = ad.txt;
  txt["caps"] = "status,teleop";
  auto problems = rcanctl::discovery_disagreements(txt, 8000, ad.discover);
  CHECK(names(problems, "TXT caps=status,teleop but txt_record says"));
  CHECK(names(problems, "but capabilities[] is [status,teleop,com.acme.gripper]"));

  json discover = ad.discover;
  discover["capabilities"] = {"status"};  // txt_record still right: only capabilities[] drifted
  problems = rcanctl::discovery_disagreements(ad.txt, 8000, discover);
  REQUIRE(problems.size() == 1);
  CHECK(names(problems, "capabilities[] is [status]"));

  CHECK(names(rcanctl::discovery_disagreements(advertised("estop", 8000).txt, 8000, ad.discover), "TXT status=estop"));
  CHECK(names(rcanctl::discovery_disagreements(ad.txt, 9000, ad.discover), "mDNS port 9000 but DISCOVER port is 8000"));
  txt = ad.txt;
  txt.erase("roles");
  CHECK(names(rcanctl::discovery_disagreements(txt, 8000, ad.discover), "txt_record roles is missing from TXT"));
  txt = ad.txt;
  txt["extra"] = "1";
  CHECK(names(rcanctl::discovery_disagreements(txt, 8000, ad.discover), "TXT extra is missing from txt_record"));
  CHECK(names(rcanctl::discovery_disagreements(ad.txt, 8000, json("nope")), "not a JSON object"));
}
