#include "kernel/plugins/settings_schema.hpp"

#include "libs/base/logging.hpp"

namespace rcand::kernel {

nlohmann::json plugin_settings(const RobotConfig& config, const std::string& plugin_id, const nlohmann::json& schema,
                               const nlohmann::json& settings, bool driver_entry, const std::string& path) {
  const bool strict = default_load_options().strict;
  std::vector<std::string> ignored;
  try {
    auto result = apply_config_schema(schema, settings, driver_entry, strict ? nullptr : &ignored);
    for (const auto& key : ignored) {
      const ConfigDiagnostic warning{
          ConfigDiagnostic::Severity::Warning, config.mark_of(path + "." + key), path,
          "'" + key + "' is not a setting of plugin " + plugin_id + "; ignored (a key of another runtime? --strict refuses it)"};
      logger("kernel.config")->warn("{}", warning.format());
    }
    return result;
  } catch (const ConfigSchemaError& e) {
    const std::string key_path = e.key().empty() ? path : path + "." + e.key();
    throw ConfigError({ConfigDiagnostic{ConfigDiagnostic::Severity::Error, config.mark_of(key_path), key_path,
                                        e.problem() + " (settings of plugin " + plugin_id + ")"}});
  }
}

}  // namespace rcand::kernel
