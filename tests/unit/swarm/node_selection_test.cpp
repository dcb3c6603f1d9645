// Selecting swarm nodes by name (any of) and tag (all of), with clear errors for unknown ones.
#include <doctest/doctest.h>

#include "libs/swarm/node_selection.hpp"

using namespace rcand::swarm;

namespace {

SwarmRegistry fleet() {
  return parse_swarm(R"(nodes:
  - {name: alex, host: a, token: t, tags: [rover, camera]}
  - {name: bob, host: b, token: t, tags: [rover]}
  - {name: carol, host: c, token: t, tags: [arm, camera]}
)",
                     "swarm.yaml");
}

std::vector<std::string> names(const std::variant<std::vector<SwarmNode>, SelectionError>& result) {
  std::vector<std::string> out;
  for (const auto& node : std::get<std::vector<SwarmNode>>(result)) out.push_back(node.name);
  return out;
}

}  // namespace

TEST_CASE("no filter selects every node, in file order") {
  CHECK(names(select_nodes(fleet(), {})) == std::vector<std::string>{"alex", "bob", "carol"});
}

TEST_CASE("names select any of them; tags require every tag; both filters combine") {
  CHECK(names(select_nodes(fleet(), {{"carol", "alex"}, {}})) == std::vector<std::string>{"alex", "carol"});
  CHECK(names(select_nodes(fleet(), {{}, {"camera"}})) == std::vector<std::string>{"alex", "carol"});
  CHECK(names(select_nodes(fleet(), {{}, {"camera", "rover"}})) == std::vector<std::string>{"alex"});
  CHECK(names(select_nodes(fleet(), {{"bob", "carol"}, {"camera"}})) == std::vector<std::string>{"carol"});
}

TEST_CASE("an unknown name lists the known ones; an unused tag lists the tags in use") {
  auto unknown = select_nodes(fleet(), {{"dave"}, {}});
  REQUIRE(std::holds_alternative<SelectionError>(unknown));
  CHECK(std::get<SelectionError>(unknown).field == "nodes");
  CHECK(std::get<SelectionError>(unknown).message == "unknown node 'dave'; known nodes: alex, bob, carol");
  auto tag = select_nodes(fleet(), {{}, {"lidar"}});
  REQUIRE(std::holds_alternative<SelectionError>(tag));
  CHECK(std::get<SelectionError>(tag).field == "tags");
  CHECK(std::get<SelectionError>(tag).message == "no node carries tag 'lidar'; tags in use: arm, camera, rover");
  auto empty = select_nodes(SwarmRegistry{}, {{"x"}, {}});
  CHECK(std::get<SelectionError>(empty).message == "unknown node 'x'; known nodes: (none)");
}
