#include "kernel/plugins/settings_schema.hpp"

namespace rcand::kernel {

nlohmann::json plugin_settings(const RobotConfig& config, const std::string& plugin_id, const nlohmann::json& schema,
                               const nlohmann::json& settings, bool driver_entry, const std::string& path) {
  try {
    return apply_config_schema(schema, settings, driver_entry);
  } catch (const ConfigSchemaError& e) {
    const std::string key_path = e.key().empty() ? path : path + "." + e.key();
    throw ConfigError({ConfigDiagnostic{ConfigDiagnostic::Severity::Error, config.mark_of(key_path), key_path,
                                        e.problem() + " (settings of plugin " + plugin_id + ")"}});
  }
}

}  // namespace rcand::kernel
