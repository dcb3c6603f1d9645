#include "libs/config/foreign_keys.hpp"

#include <array>

namespace rcand::kernel::config_detail {
namespace {

using enum ForeignKey::Origin;

// Seen in the reference runtime's presets (RCAN 1.x) and in RCAN 2.x/3.x configs. Only keys rcand has no use for:
// anything rcand reads belongs in the schema table instead.
constexpr std::array kForeignKeys{
    // RCAN 2.x and later: flattened blocks and compliance settings.
    ForeignKey{"port", NewerRcan, "rcan_protocol.port"},
    ForeignKey{"host", NewerRcan, "runtime.listen.address"},
    ForeignKey{"capabilities", NewerRcan, "rcan_protocol.capabilities"},
    ForeignKey{"brain", NewerRcan, "agent"},
    ForeignKey{"hitl_gates", NewerRcan, "agent.hitl_gates"},
    ForeignKey{"hardware_safety", NewerRcan},
    ForeignKey{"authority_handler_enabled", NewerRcan},
    ForeignKey{"audit_retention_days", NewerRcan, "runtime.audit_keep_files"},
    ForeignKey{"metadata.rrn", NewerRcan, "metadata.ruri"},
    ForeignKey{"metadata.rrn_uri", NewerRcan, "metadata.ruri"},
    ForeignKey{"metadata.version", NewerRcan},
    ForeignKey{"agent.runtimes", NewerRcan, "agent.provider"},
    ForeignKey{"safety.local_safety_wins", NewerRcan},
    ForeignKey{"safety.watchdog", NewerRcan, "safety.watchdog_ms"},
    ForeignKey{"safety.min_obstacle_m", NewerRcan, "agent.min_obstacle_m"},
    ForeignKey{"safety.latency_budget_ms", NewerRcan, "agent.latency_budget_ms"},
    // Other runtimes' own settings.
    ForeignKey{"metadata.author", OtherRuntime},
    ForeignKey{"metadata.license", OtherRuntime},
    ForeignKey{"metadata.tags", OtherRuntime},
    ForeignKey{"metadata.created_at", OtherRuntime},
    ForeignKey{"agent.vision_enabled", OtherRuntime},
    ForeignKey{"agent.safety_stop", OtherRuntime},
    ForeignKey{"agent.api_key", OtherRuntime, "runtime.capabilities.chat.brains"},
    ForeignKey{"agent.secondary_models", OtherRuntime, "agent.fallbacks"},
    ForeignKey{"agent.offline_provider", OtherRuntime, "agent.fallbacks"},
    ForeignKey{"physics.chassis", OtherRuntime, "physics.wheel_base_m"},
    ForeignKey{"camera.depth_enabled", OtherRuntime, "camera.depth"},
    ForeignKey{"camera.camera_required", OtherRuntime},
    ForeignKey{"camera.imu_enabled", OtherRuntime},
    ForeignKey{"camera.index", OtherRuntime, "camera.device"},
    ForeignKey{"camera.role", OtherRuntime},
    ForeignKey{"camera.id", OtherRuntime},
    ForeignKey{"rcan_protocol.registry", OtherRuntime},
    ForeignKey{"safety.max_linear_speed_mps", OtherRuntime, "safety.max_linear_speed"},
    ForeignKey{"safety.max_angular_speed_radps", OtherRuntime},
    ForeignKey{"safety.voltage_monitoring", OtherRuntime},
    ForeignKey{"audio", OtherRuntime},
    ForeignKey{"channels", OtherRuntime},
    ForeignKey{"connection", OtherRuntime},
    ForeignKey{"notes", OtherRuntime},
};

}  // namespace

const ForeignKey* find_foreign_key(std::string_view key_path) noexcept {
  for (const auto& key : kForeignKeys)
    if (key.path == key_path) return &key;
  return nullptr;
}

}  // namespace rcand::kernel::config_detail
