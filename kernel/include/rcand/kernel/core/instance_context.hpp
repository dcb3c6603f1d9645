// The sdk::PluginContext the kernel hands each plugin instance. Owns the instance's named workers.
#pragma once

#include <deque>
#include <memory>
#include <mutex>
#include <string>

#include "rcand/kernel/core/estop.hpp"
#include "rcand/kernel/core/instance_health.hpp"
#include "rcand/kernel/core/kernel_motion_gate.hpp"
#include "rcand/kernel/core/logging.hpp"
#include "rcand/kernel/core/worker_thread.hpp"
#include "rcand/sdk/context.hpp"

namespace rcand::kernel {

// Kernel services every context shares; they outlive all instances.
struct KernelServices {
  const sdk::Clock& clock;
  Estop& estop;
  KernelMotionGate& gate;
  const sdk::ConfigView& robot_config;
};

class InstanceContext final : public sdk::PluginContext {
 public:
  InstanceContext(std::string plugin_id, std::string instance_id, KernelServices& services, nlohmann::json settings,
                  InstanceHealth& health);
  ~InstanceContext() override;  // joins workers

  std::string_view plugin_id() const noexcept override { return plugin_id_; }
  std::string_view instance_id() const noexcept override { return instance_id_; }
  sdk::Logger& log() noexcept override { return logger_; }
  const sdk::Clock& clock() const noexcept override { return services_.clock; }
  sdk::EstopView& estop() noexcept override { return services_.estop; }
  sdk::MotionGate& motion() noexcept override { return services_.gate; }
  const sdk::ConfigView& config() const noexcept override { return settings_; }
  const sdk::ConfigView& robot_config() const noexcept override { return services_.robot_config; }
  sdk::Worker& worker(std::string_view name) override;

  // Joins every worker this instance created (their queued tasks finish first). Idempotent.
  void join_workers();

 private:
  std::string plugin_id_, instance_id_;
  KernelServices& services_;
  PluginLogger logger_;
  sdk::ConfigView settings_;
  InstanceHealth& health_;
  std::mutex workers_mutex_;  // guards workers_ creation only
  std::deque<std::unique_ptr<WorkerThread>> workers_;
};

}  // namespace rcand::kernel
