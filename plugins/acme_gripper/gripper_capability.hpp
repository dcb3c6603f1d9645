// Capability "com.acme.gripper": GET /api/cap/com.acme.gripper/state and POST .../grip.
#pragma once

#include <rcand/sdk/plugin.hpp>

#include <mutex>
#include <optional>
#include <string>

#include "gripper.hpp"

namespace acme::gripper {

class GripperCapability final : public rcand::sdk::Capability {
 public:
  explicit GripperCapability(rcand::sdk::PluginContext& ctx);
  std::vector<rcand::sdk::Route> routes() override;
  rcand::sdk::Json status() const override;

 private:
  rcand::sdk::Response state(const rcand::sdk::Request& request);
  rcand::sdk::Response grip(const rcand::sdk::Request& request);
  std::optional<std::string> resolve_actuator() const;  // setting `driver`, else the first com.acme.gripper
  rcand::sdk::Json describe(const std::string& actuator) const;
  // Caches what status() serves without touching the gate; true when that changed.
  bool remember(const Gripper& gripper);
  // Hands the kernel status() as it is now (PluginContext::publish_status), after each change.
  void publish() noexcept;

  rcand::sdk::PluginContext& ctx_;
  const std::optional<std::string> configured_driver_;
  mutable std::mutex mutex_;  // guards the cached state below
  std::optional<double> opening_;
  bool holding_ = false;
};

}  // namespace acme::gripper
