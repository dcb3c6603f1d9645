// rcand assembled: config → plugins → capability registry → safety → HTTP. Embeddable (tests, benchmarks);
// the daemon's main is a thin wrapper around it.
#pragma once

#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "kernel/plugins/plugin_host.hpp"
#include "kernel/registry/capability_registry.hpp"
#include "libs/config/robot_config.hpp"

namespace rcand::kernel {

inline constexpr std::string_view kRcandVersion = "0.1.0";

// A startup refusal that is not a config-file error (unsafe auth mode, unreadable secret, port in use).
class StartupError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Service;  // kernel/service.hpp
struct ServiceHost;

struct KernelOptions {
  std::optional<std::vector<std::filesystem::path>> plugin_paths;  // replaces runtime.plugin_paths
  std::optional<std::uint16_t> port;                               // replaces the configured port
  // The optional services to run (kernel/service.hpp), in start order; rcand's main passes linked_services().
  std::vector<std::function<std::unique_ptr<Service>(ServiceHost&)>> services;
  // What the services read besides config keys, checked by check() as at startup; rcand's main passes linked_service_checks().
  std::vector<std::function<void(const config::RobotConfig&)>> service_checks;
  // A kernel that never serves (tests and fuzzers that embed it and call its Api directly): it claims neither the
  // state dir nor a port, and start() refuses.
  bool embedded = false;
  // Called on the starter thread once every capability is up or failed (rcand's main announces it on stdout); not
  // when shut down first. An embedded kernel starts them before its constructor returns.
  std::function<void()> on_capabilities_up;
};
inline KernelOptions embedded_kernel_options() {
  KernelOptions options;
  options.embedded = true;
  return options;
}

// Admin-installed plugins first (they are found first, so they win), then the packaged ones.
std::vector<std::filesystem::path> default_plugin_paths();

class Api;

class Kernel {
 public:
  // Claims the robot first - runtime.state_dir's lock (one rcand per robot) and the listening port(s), bound but
  // not yet listening - so that a second rcand is refused before any plugin instance exists: it opens no device
  // and writes nothing (not with KernelOptions::embedded). Then loads plugins, plans capabilities, starts every
  // driver and declares every capability (an embedded kernel starts them too; a serving one once start() serves).
  // Throws ConfigError (with file:line:column) or StartupError.
  Kernel(config::RobotConfig config, KernelOptions options = {});
  ~Kernel();  // shutdown()
  Kernel(const Kernel&) = delete;
  Kernel& operator=(const Kernel&) = delete;

  // rcand --check-config: loads the plugins the config needs and checks every driver, capability and setting against
  // them (PluginRuntime::check) without starting anything: no plugin instance, no device opened, no file written, no
  // socket. Returns the capability names and, per actuating driver, the hardware fail-safe its manifest states (or a
  // warning that it states none); throws ConfigError with every problem found, or StartupError.
  struct CheckReport {
    std::vector<std::string> capabilities;
    std::vector<std::string> fail_safes;  // "drive0 (sim_diff_drive): <fail-safe>"
  };
  static CheckReport check(config::RobotConfig config, const KernelOptions& options);

  // Restores the e-stop latch from the state dir, then serves on the port claimed and starts the capabilities on a
  // thread of their own (each answers 503 STARTING until it is up); returns the port. std::logic_error for an
  // embedded kernel.
  std::uint16_t start();
  // With runtime.listen.tls: the plain HTTP port on 127.0.0.1 (after start); else 0.
  std::uint16_t plain_loopback_port() const;
  // The e-stop path runs first (motors halt), then HTTP stops, then plugins shut down. Idempotent.
  void shutdown() noexcept;
  // Whether the thread that reads and handles the e-stop answers within `within` (the service watchdog's check).
  bool stop_path_responsive(std::chrono::milliseconds within) const;

  // Config reload (SIGHUP): re-reads `file`. Invalid (a config error with file:line:column, an unreadable JWT secret,
  // a file a service refuses - Service::prepare_reload): logged, nothing changes. Valid: applies what can change while
  // serving - runtime.auth (tokens, JWT secret), runtime.logging.level and what the services take (the swarm file, the
  // R2R peers file) - and names every other changed key as needing a restart. Logged and recorded in the audit log either way.
  // Main thread; never throws.
  struct ReloadReport {
    bool ok = false;
    std::vector<std::string> errors;         // what made it invalid
    std::vector<std::string> applied;        // changed keys now in force
    std::vector<std::string> needs_restart;  // changed keys that take effect at the next start
  };
  ReloadReport reload(const std::filesystem::path& file) noexcept;

  const PluginHost& plugins() const noexcept;
  const CapabilityRegistry& registry() const noexcept;
  Api& api() noexcept;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace rcand::kernel
