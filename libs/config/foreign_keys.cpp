#include "libs/config/foreign_keys.hpp"

#include <array>

namespace rcand::config::detail {
namespace {

using enum ForeignKey::Origin;

// The rule: every key the reference runtime's config schema defines and rcand's table does not, at the level the
// schema defines it (its blocks allow any key below them, so a block of its own is ignored whole), plus the keys of
// RCAN 2.x/3.x. Only keys rcand has no use for: anything rcand reads belongs in the schema table instead. A near miss
// of one of rcand's own keys that is in neither list stays an error ("rcan_protocl").
constexpr std::array kForeignKeys{
    // RCAN 2.x and later (the RCAN 2.x/3.x spec and its SDK, continuonai/rcan-py rcan/validate.py): flattened blocks
    // and compliance settings.
    ForeignKey{"port", NewerRcan, "rcan_protocol.port"},
    ForeignKey{"host", NewerRcan, "runtime.listen.address"},
    ForeignKey{"capabilities", NewerRcan, "rcan_protocol.capabilities"},
    ForeignKey{"brain", NewerRcan, "agent"},
    ForeignKey{"hitl_gates", NewerRcan, "agent.hitl_gates"},
    ForeignKey{"hardware_safety", NewerRcan},
    ForeignKey{"authority_handler_enabled", NewerRcan},
    ForeignKey{"audit_retention_days", NewerRcan, "runtime.audit_keep_files"},
    ForeignKey{"firmware_hash", NewerRcan},
    ForeignKey{"attestation_ref", NewerRcan},
    ForeignKey{"fria_ref", NewerRcan},
    ForeignKey{"metadata.rrn", NewerRcan, "metadata.ruri"},
    ForeignKey{"metadata.rrn_uri", NewerRcan, "metadata.ruri"},
    ForeignKey{"metadata.version", NewerRcan},
    ForeignKey{"metadata.device_id", NewerRcan, "metadata.robot_uuid"},
    ForeignKey{"metadata.hardware_version", NewerRcan},
    ForeignKey{"agent.runtimes", NewerRcan, "agent.provider"},
    ForeignKey{"agent.commitment_chain", NewerRcan},
    ForeignKey{"rcan_protocol.version", NewerRcan, "rcan_version"},
    ForeignKey{"rcan_protocol.jwt_auth", NewerRcan, "rcan_protocol.enable_jwt"},
    ForeignKey{"safety.local_safety_wins", NewerRcan},
    ForeignKey{"safety.watchdog", NewerRcan, "safety.watchdog_ms"},
    ForeignKey{"safety.min_obstacle_m", NewerRcan, "agent.min_obstacle_m"},
    ForeignKey{"safety.latency_budget_ms", NewerRcan, "agent.latency_budget_ms"},

    // The reference runtime (craigm26/OpenCastor): config/rcan.schema.json at commit
    // 466a010fd8743b9ab63d5f7d9a804a6fe77679a5, every property it defines that rcand's table does not.
    // Top level: blocks of its own (their keys are its business, ignored whole).
    ForeignKey{"tiered_brain", OtherRuntime, "agent.fallbacks"},
    ForeignKey{"reactive", OtherRuntime},
    ForeignKey{"learner", OtherRuntime},
    ForeignKey{"audio", OtherRuntime},
    ForeignKey{"channels", OtherRuntime},
    ForeignKey{"agent_roster", OtherRuntime, "agent"},
    ForeignKey{"swarm", OtherRuntime, "runtime.swarm_file"},
    ForeignKey{"connection", OtherRuntime},
    ForeignKey{"notes", OtherRuntime},
    ForeignKey{"ros2", OtherRuntime},
    ForeignKey{"p66", OtherRuntime},
    ForeignKey{"consent", OtherRuntime},
    ForeignKey{"loa", OtherRuntime},
    ForeignKey{"r2ram", OtherRuntime},
    ForeignKey{"security", OtherRuntime},
    ForeignKey{"transport", OtherRuntime},
    ForeignKey{"cameras", OtherRuntime, "camera"},
    ForeignKey{"geofence", OtherRuntime},
    ForeignKey{"federation", OtherRuntime, "runtime.r2r"},
    ForeignKey{"multimodal", OtherRuntime},
    ForeignKey{"offline", OtherRuntime},
    ForeignKey{"human_identity", OtherRuntime},
    ForeignKey{"owner", OtherRuntime},
    ForeignKey{"firebase_uid", OtherRuntime},
    ForeignKey{"cloud", OtherRuntime},
    ForeignKey{"_note", OtherRuntime},
    ForeignKey{"provider_fallback", OtherRuntime, "agent.fallbacks"},
    ForeignKey{"circuit_breaker", OtherRuntime},
    ForeignKey{"context_compressor", OtherRuntime},
    ForeignKey{"cost_meter", OtherRuntime},
    ForeignKey{"dlq", OtherRuntime},
    ForeignKey{"prompt_guard", OtherRuntime},
    ForeignKey{"rollback", OtherRuntime},
    ForeignKey{"span_tracer", OtherRuntime},
    ForeignKey{"working_memory", OtherRuntime},
    ForeignKey{"jwt_auth", OtherRuntime, "runtime.auth"},
    // metadata
    ForeignKey{"metadata.author", OtherRuntime},
    ForeignKey{"metadata.license", OtherRuntime},
    ForeignKey{"metadata.tags", OtherRuntime},
    ForeignKey{"metadata.created_at", OtherRuntime},
    // agent
    ForeignKey{"agent.vision_enabled", OtherRuntime},
    ForeignKey{"agent.safety_stop", OtherRuntime},
    ForeignKey{"agent.api_key", OtherRuntime, "runtime.capabilities.chat.brains"},
    ForeignKey{"agent.base_url", OtherRuntime, "runtime.capabilities.chat.brains"},
    ForeignKey{"agent.endpoint_url", OtherRuntime, "runtime.capabilities.chat.brains"},
    ForeignKey{"agent.loop_sleep_s", OtherRuntime},
    ForeignKey{"agent.agentic_vision", OtherRuntime},
    ForeignKey{"agent.tools", OtherRuntime},
    ForeignKey{"agent.secondary_models", OtherRuntime, "agent.fallbacks"},
    ForeignKey{"agent.prompt_caching", OtherRuntime},
    ForeignKey{"agent.cache_alert_threshold", OtherRuntime},
    ForeignKey{"agent.fast_provider", OtherRuntime, "agent.fallbacks"},
    ForeignKey{"agent.fast_model", OtherRuntime, "agent.fallbacks"},
    ForeignKey{"agent.slow_provider", OtherRuntime, "agent.fallbacks"},
    ForeignKey{"agent.slow_model", OtherRuntime, "agent.fallbacks"},
    ForeignKey{"agent.provider_fallback", OtherRuntime, "agent.fallbacks"},
    ForeignKey{"agent._note", OtherRuntime},
    ForeignKey{"agent.nexa_enabled", OtherRuntime},
    ForeignKey{"agent.nexa_model", OtherRuntime},
    ForeignKey{"agent.whisper_model", OtherRuntime},
    ForeignKey{"agent.system_prompt", OtherRuntime},
    ForeignKey{"agent.temperature", OtherRuntime},
    ForeignKey{"agent.max_tokens", OtherRuntime},
    ForeignKey{"agent.offline_provider", OtherRuntime, "agent.fallbacks"},
    ForeignKey{"agent.max_context_tokens", OtherRuntime},
    ForeignKey{"agent.streaming", OtherRuntime},
    ForeignKey{"agent.json_mode", OtherRuntime},
    ForeignKey{"agent.use_oauth", OtherRuntime},
    // physics, camera, rcan_protocol, safety
    ForeignKey{"physics.chassis", OtherRuntime, "physics.wheel_base_m"},
    ForeignKey{"camera.depth_enabled", OtherRuntime, "camera.depth"},
    ForeignKey{"camera.imu_enabled", OtherRuntime},
    ForeignKey{"rcan_protocol.registry", OtherRuntime},
    ForeignKey{"safety.motor_rate_hz", OtherRuntime},
    // Keys of its driver entries that rcand's plugins take no setting for (checked against each plugin's own
    // settings: one the plugin names is the plugin's). `_note` is its free-text comment, as at the top level.
    ForeignKey{"drivers[].link_id", OtherRuntime},
    ForeignKey{"drivers[].hardware_id", OtherRuntime},
    ForeignKey{"drivers[].frequency", OtherRuntime},
    ForeignKey{"drivers[].steering_channel", OtherRuntime},
    ForeignKey{"drivers[].steering_center_us", OtherRuntime},
    ForeignKey{"drivers[].steering_range_us", OtherRuntime},
    ForeignKey{"drivers[].steering_invert", OtherRuntime},
    ForeignKey{"drivers[].throttle_channel", OtherRuntime},
    ForeignKey{"drivers[].throttle_neutral_us", OtherRuntime},
    ForeignKey{"drivers[].throttle_max_us", OtherRuntime},
    ForeignKey{"drivers[].throttle_min_us", OtherRuntime},
    ForeignKey{"drivers[].throttle_deadzone", OtherRuntime},
    ForeignKey{"drivers[]._note", OtherRuntime},
    ForeignKey{"drivers[].note", OtherRuntime},
    ForeignKey{"drivers[].notes", OtherRuntime},

    // Other runtimes' camera keys (the reference runtime's camera manager, castor/camera.py).
    ForeignKey{"camera.camera_required", OtherRuntime},
    ForeignKey{"camera.index", OtherRuntime, "camera.device"},
    ForeignKey{"camera.role", OtherRuntime},
    ForeignKey{"camera.id", OtherRuntime},
    ForeignKey{"safety.max_linear_speed_mps", OtherRuntime, "safety.max_linear_speed"},
    ForeignKey{"safety.max_angular_speed_radps", OtherRuntime},
    ForeignKey{"safety.voltage_monitoring", OtherRuntime},
};

}  // namespace

const ForeignKey* find_foreign_key(std::string_view key_path) noexcept {
  for (const auto& key : kForeignKeys)
    if (key.path == key_path) return &key;
  return nullptr;
}

}  // namespace rcand::config::detail

namespace rcand::config {

bool is_foreign_driver_key(std::string_view key) noexcept {
  for (const auto& foreign : detail::kForeignKeys)
    if (foreign.path.starts_with("drivers[].") && foreign.path.substr(10) == key) return true;
  return false;
}

std::vector<std::string> take_foreign_settings(nlohmann::json& settings, const nlohmann::json& properties, bool driver_entry,
                                               const std::string& path) {
  std::vector<std::string> taken;
  if (!settings.is_object()) return taken;
  for (auto it = settings.begin(); it != settings.end();) {
    const bool named = properties.is_object() && properties.contains(it.key());
    const bool others =
        driver_entry ? is_foreign_driver_key(it.key()) : detail::find_foreign_key(path + "." + it.key()) != nullptr;
    if (named || !others) {
      ++it;
      continue;
    }
    taken.push_back(it.key());
    it = settings.erase(it);
  }
  return taken;
}

}  // namespace rcand::config
