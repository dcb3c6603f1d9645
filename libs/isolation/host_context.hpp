// The sdk::PluginContext an isolated capability gets in its host process (rcand-plugin-host): the plugin is built
// against the SDK alone and cannot tell. Its log lines, published statuses, e-stop requests and calls on actuators go
// to rcand over the channel (rcand's gate decides every motion); its settings and the robot config came with the start
// message; its workers are threads of the host. Of the typed services, rcand's metrics (remote_metrics.hpp), its request
// dispatcher (remote_dispatcher.hpp), the robot's pose (remote_pose.hpp) and an obstacle source the plugin offers
// (remote_obstacles.hpp) are carried; other services are objects in one address space: what the plugin offers is found
// by the plugin alone (chat's own brains), and what other plugins offer is not found.
#pragma once

#include <nlohmann/json.hpp>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "libs/base/steady_clock.hpp"
#include "libs/base/worker_thread.hpp"
#include "libs/isolation/actuator_calls.hpp"
#include "libs/isolation/channel.hpp"
#include "libs/isolation/remote_dispatcher.hpp"
#include "libs/isolation/remote_metrics.hpp"
#include "libs/isolation/remote_obstacles.hpp"
#include "libs/isolation/remote_pose.hpp"
#include "rcand/sdk/context.hpp"

namespace rcand::isolation {

class HostContext final : public sdk::PluginContext {
 public:
  HostContext(Channel& channel, const nlohmann::json& start);
  ~HostContext() override;  // joins the workers

  std::string_view plugin_id() const noexcept override { return plugin_id_; }
  std::string_view instance_id() const noexcept override { return instance_id_; }
  sdk::Logger& log() noexcept override { return logger_; }
  const sdk::Clock& clock() const noexcept override { return clock_; }
  sdk::EstopView& estop() noexcept override { return estop_; }
  sdk::MotionGate& motion() noexcept override { return gate_; }
  const sdk::ConfigView& config() const noexcept override { return settings_; }
  const sdk::ConfigView& robot_config() const noexcept override { return robot_config_; }
  sdk::Worker& worker(std::string_view name) override;
  void publish_status(const nlohmann::json& status) noexcept override;
  const void* service(std::string_view interface_id) const noexcept override;
  bool offer_service(std::string_view interface_id, const void* service) noexcept override;

  // From the session: rcand's latch as its last message said, a reply to one of this host's calls, and the channel's
  // end (every call still waiting then returns ActuatorFailed).
  void set_latched(bool latched);
  void deliver(const nlohmann::json& reply);
  void close();
  // The plugin's workers, its dispatches' answers and the obstacle poller ended: before its objects are destroyed.
  void join_workers();
  RemoteDispatcher& dispatcher() noexcept { return dispatcher_; }
  RemotePose& pose() noexcept { return pose_; }

  // One call to rcand and its answer ({"gate", "result", "error"?}); blocks until rcand answers or the channel ends.
  nlohmann::json call(std::string_view op, std::string_view actuator, std::string_view method, nlohmann::json args);

 private:
  class Log final : public sdk::Logger {
   public:
    explicit Log(Channel& channel) : channel_(channel) {}
    void log(sdk::LogLevel level, std::string_view message) noexcept override;

   private:
    Channel& channel_;
  };
  class Estop final : public sdk::EstopView {
   public:
    explicit Estop(HostContext& host) : host_(host) {}
    bool latched() const noexcept override { return host_.latched_.load(); }
    bool sleep_unless_latched(std::chrono::microseconds duration) const override;
    void request_estop(const std::string& reason) noexcept override;

   private:
    HostContext& host_;
  };
  class Gate final : public sdk::MotionGate {
   public:
    Gate(HostContext& host, std::vector<sdk::ActuatorInfo> actuators) : host_(host), actuators_(std::move(actuators)) {}
    sdk::GateStatus actuate(std::string_view actuator_id, const std::function<void(sdk::ActuatorDriver&)>& command) override;
    void halt(std::string_view actuator_id) noexcept override;
    std::vector<sdk::ActuatorInfo> actuators() const override { return actuators_; }
    sdk::GateStatus inspect(std::string_view actuator_id,
                            const std::function<void(const sdk::ActuatorDriver&)>& reader) const override;

   private:
    // `use` run on a stand-in for `actuator_id` whose calls are sent as `op`; the first refusal of those calls, or why
    // there is no stand-in (an unknown actuator, an interface not carried).
    sdk::GateStatus through_stand_in(std::string_view actuator_id, std::string_view op,
                                     const std::function<void(sdk::ActuatorDriver&)>& use) const;
    HostContext& host_;
    const std::vector<sdk::ActuatorInfo> actuators_;
  };

  Channel& channel_;
  std::string plugin_id_, instance_id_;
  SteadyClock clock_;
  Log logger_{channel_};
  Estop estop_{*this};
  Gate gate_;
  RemoteMetrics metrics_{channel_};
  RemoteDispatcher dispatcher_{channel_};
  RemotePose pose_;
  sdk::ConfigView settings_, robot_config_;
  std::atomic<bool> latched_{false};

  mutable std::mutex mutex_;
  std::condition_variable changed_;
  bool closed_ = false;
  std::uint64_t next_call_ = 0;
  std::map<std::uint64_t, std::optional<nlohmann::json>> calls_;
  std::deque<std::unique_ptr<WorkerThread>> workers_;
  std::unique_ptr<ObstaclePoller> obstacles_;  // once the plugin offered its obstacle source and rcand took it
  std::map<std::string, const void*, std::less<>> local_services_;  // offered by the plugin, found by it alone
};

}  // namespace rcand::isolation
