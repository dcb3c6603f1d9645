// What a plugin's manifest says about configuring it, for people: `rcand --describe ID` (a terminal) and
// docs/drivers.md (`rcand --describe --markdown`), from the manifests alone (nothing is loaded). For each driver
// protocol or capability: its description and fail-safe, the table of its settings (name, type, default, range,
// required, description; claims and rules), the config blocks it reads, and each example from the manifest as the
// drivers: / runtime.capabilities: / block YAML that rcand --check-config accepts.
#pragma once

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace rcand::plugin_docs {

// One installed manifest, as read from its file (the key order of the examples is kept).
struct ManifestText {
  std::string file;
  nlohmann::ordered_json document;
};

// Text for a terminal about what `id` names: a plugin id (all it provides), a driver protocol or a capability name;
// nullopt when no manifest provides it.
std::optional<std::string> describe_text(const std::vector<ManifestText>& manifests, const std::string& id);

// The Markdown reference of everything the manifests provide (docs/drivers.md), or of what `id` names (nullopt: none).
std::optional<std::string> describe_markdown(const std::vector<ManifestText>& manifests, const std::string& id = "");

// Every name describe_text() takes, sorted: plugin ids, driver protocols, capability names.
std::vector<std::string> describable(const std::vector<ManifestText>& manifests);

// The example blocks describe_text() prints for `id`, as YAML texts (for tests: each must pass --check-config).
std::vector<std::string> example_blocks(const std::vector<ManifestText>& manifests, const std::string& id);

}  // namespace rcand::plugin_docs
