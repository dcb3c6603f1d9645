// What the kernel hands a plugin instance. The context outlives the instance; references it returns stay
// valid for the instance's life.
//
// ABI minors: what each one appended to PluginContext (never pure, so a plugin built for an older minor loads
// unchanged; a plugin built with a newer SDK declares the newer minor, which an older kernel refuses, because its
// contexts lack the methods the plugin may call).
//   1.0  everything up to worker(), obstacles(), r2r()
//   1.1  publish_status()
//   1.2  service() and offer_service(): typed services between plugins (rcand/sdk/services.hpp); obstacles() became
//        find<ObstacleSource>(), and it and r2r() are kept as deprecated shims until ABI 2; also
//        Capability::stream_routes() (rcand/sdk/stream.hpp): binary and streaming answers, called only for 1.2 plugins
//   1.3  Request::scopes and Request::credential (rcand/sdk/http.hpp), appended: what the caller's credential grants,
//        and the credential itself for RequestDispatcher (rcand.request_dispatcher/3), which authorizes the caller
//        again at dispatch. A 1.3 plugin reads them, so a 1.2 kernel (whose requests lack them) refuses it
#pragma once

#include <string_view>

#include "rcand/sdk/clock.hpp"
#include "rcand/sdk/config_view.hpp"
#include "rcand/sdk/estop_view.hpp"
#include "rcand/sdk/http.hpp"
#include "rcand/sdk/interfaces/obstacle_source.hpp"
#include "rcand/sdk/logger.hpp"
#include "rcand/sdk/motion_gate.hpp"
#include "rcand/sdk/r2r.hpp"
#include "rcand/sdk/services.hpp"
#include "rcand/sdk/worker.hpp"

namespace rcand::sdk {

// Every method: any thread, never blocks, never throws except worker() on an invalid name.
class RCAND_INTERFACE PluginContext {
 public:
  virtual ~PluginContext() = default;
  virtual std::string_view plugin_id() const noexcept = 0;    // the manifest id, e.g. "com.acme.gripper"
  virtual std::string_view instance_id() const noexcept = 0;  // capability name, or the driver's config `id`
  virtual Logger& log() noexcept = 0;                         // spdlog logger "plugin.<id>"
  virtual const Clock& clock() const noexcept = 0;
  virtual EstopView& estop() noexcept = 0;
  virtual MotionGate& motion() noexcept = 0;
  // This instance's own settings, validated against the manifest's "config" schema with defaults filled in:
  // a driver's `drivers[]` entry, or a capability's `runtime.capabilities.<name>` block.
  virtual const ConfigView& config() const noexcept = 0;
  // The whole robot config (.rcan.yaml) as JSON, without the `runtime.auth` secrets; in rcand its
  // rcan_protocol.capabilities lists what the robot declares (auto-detected and self-declared ones included).
  virtual const ConfigView& robot_config() const noexcept = 0;
  // A named worker thread ("<instance>.<name>"), created on first use, joined by the kernel at shutdown.
  virtual Worker& worker(std::string_view name) = 0;
  // Deprecated since 1.2: find<ObstacleSource>(ctx), which this returns in rcand (null when nothing offers one).
  virtual const ObstacleSource* obstacles() const noexcept { return nullptr; }
  // Robot-to-robot messages (docs/protocol.md §11) through the kernel's R2R transports, or null when this kernel has
  // no R2R. The fleet plugin (org.rcand.fleet) runs the auctions on its link and prices bids with the TripEstimator
  // it finds. Deprecated since 1.2: find<R2rLinks>(ctx)->make_link(...), which this calls once per instance; kept
  // until ABI 2.
  virtual R2rLink* r2r() noexcept { return nullptr; }
  // ABI 1.1: hands the kernel this instance's status - the value status() would return now - so GET /api/status
  // serves it from a snapshot instead of calling status() per request. Publish on change: after each state change,
  // and something that changes continuously (a pose while driving) at most about 10 times a second. The kernel keeps
  // the latest value and coalesces its rebuilds, so publishing more often only costs copies. An instance that has
  // not published for a second is asked through status() instead; one that neither publishes nor answers is shown
  // stale. Any thread, never blocks beyond a copy and a brief lock. Appended last and not pure: older plugins still
  // load; a plugin built with it declares minor 1, which a 1.0 kernel (whose contexts lack it) refuses to load.
  virtual void publish_status(const Json& status) noexcept { (void)status; }
  // ABI 1.2, typed services between plugins; use them through find<T>() and offer<T>() in rcand/sdk/services.hpp,
  // which also states the rules. The object offered as `interface_id`, or null: nothing offers it (a 1.1 host's
  // answer too). Any thread, never blocks (lock-free in rcand).
  virtual const void* service(std::string_view interface_id) const noexcept {
    (void)interface_id;
    return nullptr;
  }
  // Offers `service`, an object of the interface `interface_id` that this instance owns, to every plugin and to
  // rcand. false: refused (another instance offers the id, or the id is empty or the object null; logged). Any
  // thread, never blocks beyond a brief lock.
  virtual bool offer_service(std::string_view interface_id, const void* service) noexcept {
    (void)interface_id;
    (void)service;
    return false;
  }
};

}  // namespace rcand::sdk
