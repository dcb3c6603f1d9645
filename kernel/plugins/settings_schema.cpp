#include "kernel/plugins/settings_schema.hpp"

#include "libs/base/logging.hpp"
#include "libs/config/foreign_keys.hpp"

namespace rcand::kernel {

nlohmann::json plugin_settings(const RobotConfig& config, const std::string& plugin_id, const nlohmann::json& schema,
                               const nlohmann::json& settings, bool driver_entry, const std::string& path,
                               std::vector<sdk::contract::Claim>* claims) {
  using sdk::contract::UnknownKeys;
  const bool strict = default_load_options().strict;
  const sdk::contract::SettingsRules rules{
      driver_entry ? std::span<const std::string_view>(sdk::contract::kDriverEntryKeys) : std::span<const std::string_view>(),
      driver_entry || strict ? UnknownKeys::Refuse : UnknownKeys::WarnUnlessNearMiss};
  // Another runtime's keys (a driver entry's link_id, frequency, ...; camera.depth_enabled) are ignored with a warning,
  // unless the plugin names them.
  nlohmann::json own = settings;
  std::vector<std::string> foreign;
  if (own.is_object()) {
    const nlohmann::json root = sdk::contract::settings_root(schema);
    const nlohmann::json properties = root.value("properties", nlohmann::json::object());
    for (auto it = own.begin(); it != own.end();) {
      const bool named = properties.is_object() && properties.contains(it.key());
      const bool others =
          driver_entry ? is_foreign_driver_key(it.key()) : config_detail::find_foreign_key(path + "." + it.key()) != nullptr;
      if (named || !others) {
        ++it;
        continue;
      }
      foreign.push_back(it.key());
      it = own.erase(it);
    }
  }
  auto result = sdk::contract::validate_settings(schema, own, rules);
  if (!strict) result.ignored.insert(result.ignored.begin(), foreign.begin(), foreign.end());
  else
    for (const auto& key : foreign)
      result.problems.push_back({key, "'" + key +
                                          "' is another runtime's key, not a setting of this plugin "
                                          "(--strict refuses it)"});
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
