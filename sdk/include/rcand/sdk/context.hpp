// What the kernel hands a plugin instance. The context outlives the instance; references it returns stay
// valid for the instance's life.
#pragma once

#include <string_view>

#include "rcand/sdk/clock.hpp"
#include "rcand/sdk/config_view.hpp"
#include "rcand/sdk/estop_view.hpp"
#include "rcand/sdk/http.hpp"
#include "rcand/sdk/logger.hpp"
#include "rcand/sdk/motion_gate.hpp"
#include "rcand/sdk/obstacle_source.hpp"
#include "rcand/sdk/r2r.hpp"
#include "rcand/sdk/worker.hpp"

namespace rcand::sdk {

// Every method: any thread, never blocks, never throws except worker() on an invalid name.
class RCAND_INTERFACE PluginContext {
 public:
  virtual ~PluginContext() = default;
  virtual std::string_view plugin_id() const noexcept = 0;    // the manifest id, e.g. "com.acme.gripper"
  virtual std::string_view instance_id() const noexcept = 0;  // capability name, or the driver's config `id`
  virtual Logger& log() noexcept = 0;                          // spdlog logger "plugin.<id>"
  virtual const Clock& clock() const noexcept = 0;
  virtual EstopView& estop() noexcept = 0;
  virtual MotionGate& motion() noexcept = 0;
  // This instance's own settings, validated against the manifest's "config" schema with defaults filled in:
  // a driver's `drivers[]` entry, or a capability's `runtime.capabilities.<name>` block.
  virtual const ConfigView& config() const noexcept = 0;
  // The whole robot config (.rcan.yaml) as JSON, without the `runtime.auth` secrets.
  virtual const ConfigView& robot_config() const noexcept = 0;
  // A named worker thread ("<instance>.<name>"), created on first use, joined by the kernel at shutdown.
  virtual Worker& worker(std::string_view name) = 0;
  // The robot's obstacle source (a driver or capability implementing ObstacleSource, e.g. vision's depth
  // zones), or null when none is configured. Appended last and not pure, so older plugins and hosts still link.
  virtual const ObstacleSource* obstacles() const noexcept { return nullptr; }
  // Robot-to-robot messages (docs/protocol.md §11) through the kernel's R2R transports, or null when this kernel has no R2R.
  // Appended last and not pure, so older plugins and hosts still link (ABI 1.x).
  virtual R2rLink* r2r() noexcept { return nullptr; }
  // ABI 1.1: hands the kernel this instance's status - the value status() would return now - so GET /api/status
  // serves it from a snapshot instead of calling status() per request. Publish on change: after each state change,
  // and something that changes continuously (a pose while driving) at most about 10 times a second. The kernel keeps
  // the latest value and coalesces its rebuilds, so publishing more often only costs copies. An instance that has
  // not published for a second is asked through status() instead; one that neither publishes nor answers is shown
  // stale. Any thread, never blocks beyond a copy and a brief lock. Appended last and not pure: older plugins still
  // load; a plugin built with it declares minor 1, which a 1.0 kernel (whose contexts lack it) refuses to load.
  virtual void publish_status(const Json& status) noexcept { (void)status; }
};

}  // namespace rcand::sdk
