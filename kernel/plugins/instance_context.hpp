// The sdk::PluginContext the kernel hands each plugin instance. Owns the instance's named workers.
#pragma once

#include <atomic>
#include <deque>
#include <memory>
#include <mutex>
#include <string>

#include "kernel/audit/audit_log.hpp"
#include "kernel/plugins/service_directory.hpp"
#include "kernel/safety/estop.hpp"
#include "kernel/safety/instance_health.hpp"
#include "kernel/safety/kernel_motion_gate.hpp"
#include "libs/base/logging.hpp"
#include "libs/base/worker_thread.hpp"
#include "rcand/sdk/context.hpp"
#include "rcand/sdk/interfaces/obstacle_source.hpp"

namespace rcand::kernel {

class InstanceContext;

// Where PluginContext::publish_status() lands: the status board (kernel/status/status_board.hpp).
class StatusSink {
 public:
  // Any plugin thread; must not block beyond a brief lock, never throws.
  virtual void publish(const InstanceContext& from, const nlohmann::json& status) noexcept = 0;

 protected:
  ~StatusSink() = default;
};

// The one sink publishes go to, attached after the plugins started (publishes before that are dropped: the sink
// polls everything once when it starts). detach() waits out publishes still inside the sink, so the sink can then
// be destroyed while plugin threads keep running and publishing.
class StatusSinkSlot {
 public:
  void attach(StatusSink* sink) noexcept { sink_.store(sink); }
  // Returns once no publish is inside the detached sink (they take microseconds). Never from inside a publish.
  void detach() noexcept;
  void publish(const InstanceContext& from, const nlohmann::json& status) noexcept;

 private:
  std::atomic<StatusSink*> sink_{nullptr};
  std::atomic<std::uint32_t> inside_{0};  // publishes between their load of sink_ and their return from it
};

// Kernel services every context shares; they outlive all instances.
struct KernelServices {
  const sdk::Clock& clock;
  Estop& estop;
  KernelMotionGate& gate;
  const sdk::ConfigView& robot_config;
  AuditLog* audit = nullptr;  // plugin-requested e-stops are audited (docs/protocol.md §6.3); null in tests without one
  std::string ruri;           // the robot's RURI, for those audit entries
  // PluginContext::publish_status() goes here (the status board attaches itself when it starts). The braces let an
  // aggregate initialization leave it out without -Wmissing-field-initializers.
  StatusSinkSlot status_sink{};
  // The services instances offer each other (PluginContext::offer_service), also read by the status board and lent
  // to rcand's in-tree services.
  ServiceDirectory directory{};
};

// The e-stop as a plugin instance sees it: request_estop() writes an audit entry naming the plugin (before the
// latch, like POST /api/stop), then latches exactly as POST /api/stop does.
class InstanceEstop final : public sdk::EstopView {
 public:
  InstanceEstop(KernelServices& services, const std::string& plugin_id, const std::string& instance_id)
      : services_(services), plugin_id_(plugin_id), instance_id_(instance_id) {}
  bool latched() const noexcept override { return services_.estop.latched(); }
  bool sleep_unless_latched(std::chrono::microseconds duration) const override {
    return services_.estop.sleep_unless_latched(duration);
  }
  void request_estop(const std::string& reason) noexcept override;

 private:
  KernelServices& services_;
  const std::string& plugin_id_;
  const std::string& instance_id_;
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
  sdk::EstopView& estop() noexcept override { return estop_; }
  sdk::MotionGate& motion() noexcept override { return services_.gate; }
  const sdk::ConfigView& config() const noexcept override { return settings_; }
  const sdk::ConfigView& robot_config() const noexcept override { return services_.robot_config; }
  sdk::Worker& worker(std::string_view name) override;
  // The deprecated shim: the ObstacleSource service.
  const sdk::ObstacleSource* obstacles() const noexcept override { return sdk::find<sdk::ObstacleSource>(*this); }
  // Created on first use; its callbacks run on this instance's worker "r2r".
  sdk::R2rLink* r2r() noexcept override;
  // To KernelServices::status_sink: a copy and a brief lock there, nothing else on the plugin's thread.
  void publish_status(const nlohmann::json& status) noexcept override { services_.status_sink.publish(*this, status); }
  // To KernelServices::directory, owned by this context; not found once this instance is failed.
  const void* service(std::string_view interface_id) const noexcept override { return services_.directory.service(interface_id); }
  bool offer_service(std::string_view interface_id, const void* service) noexcept override;

  // The instance's health, which outlives this context: the status board knows an instance by it, across reloads.
  const InstanceHealth& health() const noexcept { return health_; }

  // Withdraws every service this instance offered: before its shutdown(), and when the context goes. Idempotent.
  void withdraw_offers() noexcept { services_.directory.withdraw(this); }

  // Joins every worker this instance created (their queued tasks finish first). Idempotent.
  void join_workers();

 private:
  std::string plugin_id_, instance_id_;
  KernelServices& services_;
  PluginLogger logger_;
  InstanceEstop estop_{services_, plugin_id_, instance_id_};
  sdk::ConfigView settings_;
  InstanceHealth& health_;
  std::mutex workers_mutex_;  // guards workers_ creation only
  std::deque<std::unique_ptr<WorkerThread>> workers_;
  std::mutex r2r_mutex_;
  std::unique_ptr<sdk::R2rLink> r2r_link_;  // after workers_: destroyed (unsubscribed) first
};

}  // namespace rcand::kernel
