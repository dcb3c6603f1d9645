#include "kernel/plugins/settings_schema.hpp"

#include "libs/base/logging.hpp"

namespace rcand::kernel {

nlohmann::json plugin_settings(const RobotConfig& config, const std::string& plugin_id, const nlohmann::json& schema,
                               const nlohmann::json& settings, bool driver_entry, const std::string& path,
                               std::vector<sdk::contract::Claim>* claims) {
  using sdk::contract::UnknownKeys;
  const bool strict = default_load_options().strict;
  const sdk::contract::SettingsRules rules{
      driver_entry ? std::span<const std::string_view>(sdk::contract::kDriverEntryKeys) : std::span<const std::string_view>(),
      driver_entry || strict ? UnknownKeys::Refuse : UnknownKeys::WarnUnlessNearMiss};
  auto result = sdk::contract::validate_settings(schema, settings, rules);
  const auto key_path = [&path](const std::string& key) {
    return key.empty() ? path : path + (key.front() == '[' ? "" : ".") + key;
  };
  for (const auto& key : result.ignored) {
    const ConfigDiagnostic warning{
        ConfigDiagnostic::Severity::Warning, config.mark_of(key_path(key)), path,
        "'" + key + "' is not a setting of plugin " + plugin_id + "; ignored (a key of another runtime? --strict refuses it)"};
    logger("kernel.config")->warn("{}", warning.format());
  }
  if (claims != nullptr) *claims = std::move(result.claims);  // also when refused: the plan check names them too
  if (!result.problems.empty()) {
    std::vector<ConfigDiagnostic> errors;
    for (const auto& [key, problem] : result.problems)
      errors.push_back({ConfigDiagnostic::Severity::Error, config.mark_of(key_path(key)), key_path(key),
                        problem + " (settings of plugin " + plugin_id + ")"});
    throw ConfigError(std::move(errors));
  }
  return std::move(result.settings);
}

}  // namespace rcand::kernel
