// A driver's settings as rcand hands them to it: its manifest's settings schema through the SDK contract (the rule
// the kernel and the fake host call), so a plugin test can check that the manifest and the driver's own parser agree:
// every example in the manifest is taken by both, and whatever the parser refuses the manifest refuses first (so
// rcand --check-config names it before a start would fail).
#pragma once

#include <nlohmann/json.hpp>
#include <rcand/sdk/contract/plan.hpp>
#include <rcand/sdk/contract/settings.hpp>

#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace rcand::test {

// manifests/<file> of the source tree (or a path relative to it).
inline nlohmann::json source_manifest(const std::string& file) {
  std::ifstream in(std::string(RCAND_SOURCE_DIR) + "/" + file);
  if (!in) throw std::runtime_error("cannot read " + file);
  return nlohmann::json::parse(in);
}

struct ManifestVerdict {
  nlohmann::json settings;            // with defaults, as the driver's factory receives them
  std::vector<std::string> refusals;  // "channels.left.in1: ..." (problems and claims named twice); empty: taken
};

// `settings` of a drivers[] entry with `protocol` (id and protocol are added), as the kernel validates them.
inline ManifestVerdict manifest_verdict(const nlohmann::json& manifest, const std::string& protocol, nlohmann::json settings) {
  namespace contract = rcand::sdk::contract;
  settings["id"] = settings.value("id", "under-test");
  settings["protocol"] = protocol;
  const auto result =
      contract::validate_settings(contract::item_settings_schema(manifest, "driver", protocol), settings,
                                  contract::SettingsRules{contract::kDriverEntryKeys, contract::UnknownKeys::Refuse});
  ManifestVerdict verdict{result.settings, {}};
  for (const auto& [key, problem] : result.problems) verdict.refusals.push_back(key + ": " + problem);
  for (const auto& conflict : contract::claim_conflicts({{"drivers[0]", "driver under-test", result.claims}}))
    verdict.refusals.push_back(conflict.key + ": " + conflict.problem);
  return verdict;
}

// The whole-entry examples of a driver item's settings schema.
inline std::vector<nlohmann::json> manifest_examples(const nlohmann::json& manifest, const std::string& protocol) {
  const auto schema = rcand::sdk::contract::item_settings_schema(manifest, "driver", protocol);
  return schema.value("examples", std::vector<nlohmann::json>{});
}

}  // namespace rcand::test
