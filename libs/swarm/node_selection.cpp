#include "libs/swarm/node_selection.hpp"

#include <algorithm>
#include <set>

#include "libs/base/string_list.hpp"

namespace rcand::swarm {
namespace {

std::string join_names(const std::vector<std::string>& items) { return items.empty() ? "(none)" : join(items, ", "); }

}  // namespace

std::variant<std::vector<SwarmNode>, SelectionError> select_nodes(const SwarmRegistry& registry, const Selection& selection) {
  for (const auto& name : selection.names)
    if (registry.find(name) == nullptr)
      return SelectionError{"nodes", "unknown node '" + name + "'; known nodes: " + join_names(registry.names())};
  std::set<std::string> all_tags;
  for (const auto& node : registry.nodes) all_tags.insert(node.tags.begin(), node.tags.end());
  for (const auto& tag : selection.tags)
    if (!all_tags.count(tag))
      return SelectionError{"tags", "no node carries tag '" + tag + "'; tags in use: " +
                                        join_names(std::vector<std::string>(all_tags.begin(), all_tags.end()))};
  std::vector<SwarmNode> chosen;
  for (const auto& node : registry.nodes) {
    const bool named =
        selection.names.empty() || std::find(selection.names.begin(), selection.names.end(), node.name) != selection.names.end();
    const bool tagged = std::all_of(selection.tags.begin(), selection.tags.end(), [&](const auto& t) { return node.has_tag(t); });
    if (named && tagged) chosen.push_back(node);
  }
  return chosen;
}

}  // namespace rcand::swarm
