// GET /api/status as a snapshot (issue 14 item 6). Plugins publish their status when it changes
// (PluginContext::publish_status); the board keeps the latest of each instance and rebuilds the document on its own
// thread, "kernel.status": on a 500 ms tick (uptime_s and ages stay right) and soon after a change (a publish, an
// e-stop clear, notify()), changes coalesced into at most one rebuild per 20 ms. Of a driver only the fault is
// shown, so its publishes wait for the tick unless the fault changed or it was silent for a second. Each rebuild
// serializes the document once in two variants, e-stop latched or not, and body() hands out the one matching the
// latch now: serving the status calls no plugin code and hops no thread.
//
// An instance that has not published for a second is asked through its status() on the status thread (the status
// reader's 250 ms deadline still fails one that hangs), so plugins that never publish - ABI 1.0 ones - still appear.
// An entry that neither a publish nor an answer refreshed for two seconds gets "stale": true and "age_ms" in its
// item: a plugin that stops publishing shows as stale, not as a slow endpoint.
//
// An instance whose status carries a top-level "fault" (a non-empty string; sdk/capability.hpp) runs but cannot do
// its job - a camera with no picture: its item's state is "error" with the fault as "reason", and so is the robot's
// state, until a status without one.
//
// A capability's state also follows the actuator interfaces its manifest requires (Source::needs): "error" when every
// driver providing one is failed or reports a fault, "degraded" when some are, with a reason naming those drivers and
// the first one's device, OS error and hint (sdk/device_fault.hpp).
//
// The top-level "pose" and "nav_running" come from the PoseSource service (sdk/pose_source.hpp, offered by nav),
// read on the status thread at each rebuild - never per request.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "kernel/plugins/instance_context.hpp"
#include "kernel/plugins/plugin_host.hpp"
#include "kernel/plugins/plugin_runtime.hpp"
#include "kernel/registry/capability_registry.hpp"
#include "kernel/safety/instance_health.hpp"

namespace rcand::kernel {

class StatusBoard {
 public:
  static constexpr std::chrono::milliseconds kTick{500};
  static constexpr std::chrono::milliseconds kRebuildGap{20};
  static constexpr std::chrono::milliseconds kPollAfter{1000};
  static constexpr std::chrono::milliseconds kStaleAfter{2000};
  // when_current() waits for an instance's publishes only while it publishes at most this often (a burst of
  // kWaitBurst allowed): one that publishes faster is still shown, at most kRebuildGap late, but cannot make
  // every request wait for the next rebuild.
  static constexpr double kWaitPerSecond = 10.0;
  static constexpr double kWaitBurst = 8.0;

  // One plugin instance as the board sees it. rcand takes them from the plugin runtime (sources_of); tests make them.
  struct Source {
    std::string name;     // the capability name, or the driver id
    bool driver = false;  // listed under "drivers" (without its status), else under "capabilities"
    nlohmann::json item;  // its item's fields that never change: {"plugin"}, or {"id","protocol","plugin","actuates"}
    // The instance: failed, "state": "failed" with the reason, and never polled; the publish_status() of any context
    // made with this health (the instance's, a reload's new one too) feeds this entry. Null: it never publishes.
    const InstanceHealth* health = nullptr;
    std::function<std::optional<nlohmann::json>()> poll;  // its status(), through the status reader; empty: never
    // A capability: the actuator interfaces it needs (its manifest's `requires`). Its state follows the drivers whose
    // item names that "interface": "error" when every one of them failed, "degraded" when some did.
    std::vector<std::string> needs = {};
    // A capability that may still be starting: "state": "starting" while this is true (never polled), and once it is
    // false, item_when_up()'s fields join the item (its routes).
    const std::atomic<bool>* starting = nullptr;
    std::function<nlohmann::json()> item_when_up = {};
  };

  static constexpr std::size_t kFaultTextBytes = 600;

  // The fault a plugin's status reports (its top-level "fault", a non-empty string), cut and made safe; else nullopt.
  static std::optional<std::string> reported_fault(const nlohmann::json& status);

  // What GET /api/status says that never changes while rcand runs: ruri, name, version, rcan_version, caps, plugins.
  static nlohmann::json fixed_fields(const RobotIdentity& identity, const std::vector<std::string>& caps, const PluginHost& host,
                                     std::string_view version);
  // Every capability, then every driver, of a started runtime (which must outlive the board), polled through
  // PluginRuntime::status_of.
  static std::vector<Source> sources_of(PluginRuntime& runtime);
  // A failed instance's item fields: "reason", and "device", "os_error", "hint" when the fault has them.
  static void add_fault(nlohmann::json& item, const Fault& fault);

  // Main thread, after the plugins started and before anything is served (it adds e-stop listeners). `services`
  // (its clock, e-stop and status sink) outlives the board; `started_us` is the kernel's start on that clock.
  StatusBoard(PluginRuntime& runtime, KernelServices& services, nlohmann::json fixed, std::int64_t started_us);
  StatusBoard(std::vector<Source> sources, KernelServices& services, nlohmann::json fixed, std::int64_t started_us);
  ~StatusBoard();  // stop()
  StatusBoard(const StatusBoard&) = delete;
  StatusBoard& operator=(const StatusBoard&) = delete;

  // Main thread. Attaches to services.status_sink, asks every instance once and builds the first document before
  // returning (at most one status deadline, 250 ms, when a plugin's status() hangs), then ticks. Once.
  void start();
  // Detaches from the status sink (waiting out publishes inside it), joins the status thread and answers every
  // when_current() still waiting. Idempotent; the last document stays readable.
  void stop() noexcept;

  // Any thread, never blocks: the current document serialized, with "estopped" and "state" as the e-stop is now.
  std::shared_ptr<const std::string> body() const noexcept;
  // body() once it includes every change made before this call (a publish within the instance's rate above, an
  // instance marked failed): at once on this thread when the current document does (nearly always), else from the
  // status thread right after the rebuild that does, at most kRebuildGap plus a rebuild later. For GET /api/status,
  // so a client that changed something (or saw it changed elsewhere) reads it back. `answer` must not throw.
  void when_current(std::function<void(std::shared_ptr<const std::string>)> answer);
  // Any thread: the current document (for R2R status messages and telemetry), e-stop fields as now.
  nlohmann::json document() const;
  // Any thread: idle | running | error | estop (docs/protocol.md §5); the e-stop and failures as now, reported faults
  // and the PoseSource's busy flag as of the current document.
  std::string robot_state() const;

  // Any thread, never blocks: something the document shows changed without a publish (an instance marked failed,
  // say); a rebuild follows within kRebuildGap.
  void notify() noexcept;
  // Runs a full round (publishes taken, silent instances asked, document rebuilt) on the status thread now and
  // returns when it is done. Startup and tests; never from the status thread. A no-op once stopped.
  void refresh();

 private:
  class Impl;
  std::shared_ptr<Impl> impl_;  // shared with the e-stop listener, which may outlive the board
};

}  // namespace rcand::kernel
