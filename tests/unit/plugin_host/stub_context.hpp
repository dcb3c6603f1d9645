// The least PluginContext a fixture factory needs: nothing here is exercised beyond construction.
#pragma once

#include <rcand/sdk/export.hpp>
#include <rcand/sdk/context.hpp>

#include <stdexcept>
#include <string>

namespace rcand::test {

class StubContext final : public sdk::PluginContext, sdk::Logger, sdk::Clock, sdk::EstopView, sdk::MotionGate {
 public:
  explicit StubContext(std::string id) : id_(std::move(id)) {}
  std::string_view plugin_id() const noexcept override { return id_; }
  std::string_view instance_id() const noexcept override { return id_; }
  sdk::Logger& log() noexcept override { return *this; }
  const sdk::Clock& clock() const noexcept override { return *this; }
  sdk::EstopView& estop() noexcept override { return *this; }
  sdk::MotionGate& motion() noexcept override { return *this; }
  const sdk::ConfigView& config() const noexcept override { return config_; }
  const sdk::ConfigView& robot_config() const noexcept override { return config_; }
  sdk::Worker& worker(std::string_view) override { throw std::logic_error("StubContext has no workers"); }

 private:
  void log(sdk::LogLevel, std::string_view) noexcept override {}
  std::int64_t now_us() const noexcept override { return 0; }
  std::int64_t wall_ms() const noexcept override { return 0; }
  bool latched() const noexcept override { return false; }
  bool sleep_unless_latched(std::chrono::microseconds) const override { return true; }
  void request_estop(const std::string&) noexcept override {}
  sdk::GateStatus actuate(std::string_view, const std::function<void(sdk::ActuatorDriver&)>&) override {
    return sdk::GateStatus::UnknownActuator;
  }
  void halt(std::string_view) noexcept override {}
  std::vector<sdk::ActuatorInfo> actuators() const override { return {}; }
  sdk::GateStatus inspect(std::string_view, const std::function<void(const sdk::ActuatorDriver&)>&) const override {
    return sdk::GateStatus::UnknownActuator;
  }

  std::string id_;
  sdk::ConfigView config_;
};

}  // namespace rcand::test
