#include "libs/config/plugin_settings.hpp"

#include "libs/base/logging.hpp"
#include "libs/config/foreign_keys.hpp"

namespace rcand::config {

nlohmann::json plugin_settings(const config::RobotConfig& config, const std::string& plugin_id, const nlohmann::json& schema,
                               const nlohmann::json& settings, bool driver_entry, const std::string& path,
                               std::vector<sdk::contract::Claim>* claims) {
  using sdk::contract::UnknownKeys;
  const bool strict = config::default_load_options().strict;
  const sdk::contract::SettingsRules rules{
      driver_entry ? std::span<const std::string_view>(sdk::contract::kDriverEntryKeys) : std::span<const std::string_view>(),
      driver_entry || strict ? UnknownKeys::Refuse : UnknownKeys::WarnUnlessNearMiss};
  // Another runtime's keys (a driver entry's link_id, frequency; camera.depth_enabled): ignored with a warning.
  nlohmann::json own = settings;
  const auto foreign = config::take_foreign_settings(
      own, sdk::contract::settings_root(schema).value("properties", nlohmann::json::object()), driver_entry, path);
  // A capability's block also carries where it runs (rcand/sdk/contract/isolation.hpp), checked there.
  auto result = driver_entry ? sdk::contract::validate_settings(schema, own, rules)
                             : sdk::contract::validate_capability_settings(schema, own, rules.unknown);
  for (const auto& key : foreign)
    if (strict) result.problems.push_back({key, "another runtime's key, not a setting of this plugin (--strict)"});
    else result.ignored.push_back(key);
  const auto key_path = [&path](const std::string& key) {
    return key.empty() ? path : path + (key.front() == '[' ? "" : ".") + key;
  };
  for (const auto& key : result.ignored) {
    const yaml::ConfigDiagnostic warning{
        yaml::ConfigDiagnostic::Severity::Warning, config.mark_of(key_path(key)), path,
        "'" + key + "' is not a setting of plugin " + plugin_id + "; ignored (a key of another runtime? --strict refuses it)"};
    logger("kernel.config")->warn("{}", warning.format());
  }
  if (claims != nullptr) *claims = std::move(result.claims);  // also when refused: the plan check names them too
  if (!result.problems.empty()) {
    std::vector<yaml::ConfigDiagnostic> errors;
    for (const auto& [key, problem] : result.problems)
      errors.push_back({yaml::ConfigDiagnostic::Severity::Error, config.mark_of(key_path(key)), key_path(key),
                        problem + " (settings of plugin " + plugin_id + ")"});
    throw yaml::ConfigError(std::move(errors));
  }
  return std::move(result.settings);
}

}  // namespace rcand::config
