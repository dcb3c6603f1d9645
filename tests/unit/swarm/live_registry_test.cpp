// swarm.yaml as now (libs/swarm/live_registry.hpp): empty before the file is loaded; a reload swaps it whole while a
// request in flight keeps reading the registry it started with.
#include <doctest/doctest.h>

#include "libs/swarm/live_registry.hpp"

using namespace rcand::swarm;

TEST_CASE("LiveRegistry: empty until loaded; a replace swaps it whole and keeps the one a reader holds") {
  LiveRegistry live;
  CHECK(live.now().nodes.empty());
  live.replace(parse_swarm("nodes:\n  - {name: bravo, host: 127.0.0.1, token: t}\n", "first.yaml"));
  const SwarmRegistry& in_flight = live.now();
  REQUIRE(in_flight.names() == std::vector<std::string>{"bravo"});
  live.replace(parse_swarm("nodes:\n  - {name: charlie, host: 127.0.0.1, token: t}\n", "second.yaml"));
  CHECK(live.now().names() == std::vector<std::string>{"charlie"});
  CHECK(in_flight.names() == std::vector<std::string>{"bravo"});  // still readable: never freed while serving
  CHECK(in_flight.source != live.now().source);
}
