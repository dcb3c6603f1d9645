// rcand: the daemon. Parses the command line, loads the config, runs the kernel until SIGINT/SIGTERM; SIGHUP
// reloads the config file (Kernel::reload).
#include <pthread.h>
#include <sys/resource.h>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "kernel/kernel.hpp"
#include "kernel/service.hpp"
#include "libs/base/logging.hpp"
#include "libs/base/service_watchdog.hpp"
#include "libs/base/systemd_notify.hpp"
#include "libs/config/config_access.hpp"
#include "libs/config/driver_protocols.hpp"
#include "libs/config/robot_config.hpp"
#include "libs/plugin_docs/plugin_docs.hpp"
#include "rcand/sdk/abi.h"

namespace {

using namespace rcand;
using namespace rcand::kernel;

constexpr const char* kUsage = R"(usage: rcand [--config FILE] [--plugin-path DIR]... [--port N] [--strict]
       rcand --check-config FILE [--as-user NAME] [--strict]
       rcand --check-plugins [--config FILE] [--plugin-path DIR]...
       rcand --describe [ID] [--markdown] [--config FILE] [--plugin-path DIR]...
       rcand --version

  --config FILE        robot config (.rcan.yaml); default /etc/rcand/robot.rcan.yaml
  --plugin-path DIR    load plugins from DIR instead of runtime.plugin_paths (repeatable)
  --port N             listen on port N instead of the configured one (0: any free port)
  --check-config FILE  validate FILE (schema, drivers, capabilities and plugin settings against the installed
                       plugins) and exit; starts nothing, opens no device, writes no file
  --as-user NAME       with --check-config: also check that user NAME (the service's rcand) can read and write
                       every file, directory and device the config names
  --check-plugins      open every installed plugin, print the table, exit 1 if any failed
  --describe ID        print the settings of a driver protocol, capability or plugin id from the installed manifests
                       (types, defaults, ranges, what they claim, examples that pass --check-config); loads nothing.
                       With --markdown and no ID: the whole reference (docs/drivers.md)
  --strict             refuse a config that loads only with warnings (keys rcand ignores, values it supplies,
                       nav without its physics, another RCAN version), at start, --check-config and reload

On start, rcand prints one line "rcand: listening on http://ADDRESS:PORT" on stdout once it serves; with
runtime.listen.tls, "rcand: listening on https://ADDRESS:PORT" and then the plain loopback port's line. Capabilities
start once it serves (each answers 503 STARTING until it is up); "rcand: capabilities started" follows when every one
is up or failed.
)";

constexpr std::chrono::seconds kShutdownGrace{5};

struct Options {
  std::string config = "/etc/rcand/robot.rcan.yaml";
  std::vector<std::filesystem::path> plugin_paths;
  std::optional<std::uint16_t> port;
  bool check_config = false, check_plugins = false, strict = false;
  std::string as_user;                  // --check-config --as-user NAME
  std::optional<std::string> describe;  // --describe [ID]: "" for everything (with --markdown)
  bool markdown = false;
};

int usage_error(const std::string& message) {
  std::cerr << "rcand: " << message << "\n" << kUsage;
  return 2;
}

void print_warnings(const config::LoadedConfig& loaded) {
  for (const auto& warning : loaded.warnings) std::cerr << warning.format() << "\n";
}

KernelOptions kernel_options(const Options& options) {
  KernelOptions result;
  result.services = linked_services();  // the optional services linked into rcand (services/)
  result.service_checks = linked_service_checks();
  if (!options.plugin_paths.empty()) result.plugin_paths = options.plugin_paths;
  result.port = options.port;
  result.on_capabilities_up = [] { std::cout << "rcand: capabilities started" << std::endl; };
  return result;
}

std::vector<std::filesystem::path> plugin_paths_of(const Options& options) {
  std::vector<std::filesystem::path> paths = options.plugin_paths;
  if (paths.empty()) {
    try {
      paths = config::load_robot_config(options.config).config.runtime.plugin_paths;
      if (paths.empty()) paths = default_plugin_paths();
    } catch (const yaml::ConfigError&) {
      paths = default_plugin_paths();
    }
  }
  return paths;
}

int check_plugins(const Options& options) {
  PluginHost host;
  host.scan(plugin_paths_of(options));
  std::set<std::string> capabilities, protocols;
  for (const auto& record : host.records()) {
    if (!record->manifest) continue;
    for (const auto& item : record->manifest->provides) (item.kind == "driver" ? protocols : capabilities).insert(item.name);
  }
  host.load_needed(capabilities, protocols);
  std::cout << host.format_table();
  return host.any_failed() ? 1 : 0;
}

// --describe: from the manifests only (scanned, never opened).
int describe(const Options& options) {
  PluginHost host;
  host.scan(plugin_paths_of(options));
  std::vector<plugin_docs::ManifestText> manifests;
  for (const auto& record : host.records())
    if (record->manifest)
      manifests.push_back({record->manifest->file.string(), nlohmann::ordered_json::parse(record->manifest->text)});
  const auto text = options.markdown ? plugin_docs::describe_markdown(manifests, *options.describe)
                                     : plugin_docs::describe_text(manifests, *options.describe);
  if (text) std::cout << *text;
  if (text) return 0;
  std::string known;
  for (const auto& name : plugin_docs::describable(manifests)) known += (known.empty() ? "" : ", ") + name;
  return usage_error("--describe: no installed plugin provides '" + *options.describe + "' (known: " + known + ")");
}

// Every connection is a file descriptor: serve up to the hard limit, not the usual soft 1,024, so a thousand idle
// clients cannot keep the next POST /api/stop from being accepted.
void raise_open_files_limit() {
  rlimit files{};
  if (getrlimit(RLIMIT_NOFILE, &files) != 0 || files.rlim_cur >= files.rlim_max) return;
  files.rlim_cur = files.rlim_max;
  if (setrlimit(RLIMIT_NOFILE, &files) != 0) logger("kernel")->warn("cannot raise the open-files limit");
}

// The command line; an exit code when it is already decided (--help, --version, a usage error).
std::optional<int> parse_arguments(const std::vector<std::string>& args, Options& options) {
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    auto value = [&]() -> std::optional<std::string> {
      if (i + 1 >= args.size()) return std::nullopt;
      return args[++i];
    };
    if (arg == "--help" || arg == "-h") {
      std::cout << kUsage;
      return 0;
    } else if (arg == "--version") {
      std::cout << "rcand " << kRcandVersion << " (RCAN " << kRcanVersion << ", plugin ABI " << RCAND_ABI_MAJOR << "."
                << RCAND_ABI_MINOR << ")\n";
      return 0;
    } else if (arg == "--config" || arg == "--check-config") {
      auto v = value();
      if (!v) return usage_error(arg + " needs a file");
      options.config = *v;
      options.check_config = options.check_config || arg == "--check-config";
    } else if (arg == "--as-user") {
      auto v = value();
      if (!v) return usage_error("--as-user needs a user name");
      options.as_user = *v;
    } else if (arg == "--plugin-path") {
      auto v = value();
      if (!v) return usage_error("--plugin-path needs a directory");
      options.plugin_paths.emplace_back(std::filesystem::absolute(*v));
    } else if (arg == "--port") {
      auto v = value();
      try {
        const long port = v ? std::stol(*v) : -1;
        if (port < 0 || port > 65535) throw std::out_of_range("port");
        options.port = static_cast<std::uint16_t>(port);
      } catch (const std::exception&) {
        return usage_error("--port needs a number from 0 to 65535");
      }
    } else if (arg == "--check-plugins") {
      options.check_plugins = true;
    } else if (arg == "--describe") {
      options.describe = i + 1 < args.size() && !args[i + 1].starts_with("--") ? args[++i] : std::string();
    } else if (arg == "--markdown") {
      options.markdown = true;
    } else if (arg == "--strict") {
      options.strict = true;
    } else {
      return usage_error("unknown argument '" + arg + "'");
    }
  }

  return std::nullopt;
}

int serve(const Options& options, config::LoadedConfig loaded, sigset_t& signals) {
  const std::string address = loaded.config.runtime.listen_address;
  Kernel kernel(std::move(loaded.config), kernel_options(options));
  const auto port = kernel.start();
  if (const auto plain = kernel.plain_loopback_port())  // runtime.listen.tls: HTTPS there, plain HTTP on loopback
    std::cout << "rcand: listening on https://" << address << ":" << port << "\n"
              << "rcand: listening on http://127.0.0.1:" << plain << std::endl;
  else std::cout << "rcand: listening on http://" << address << ":" << port << std::endl;
  // Under systemd (Type=notify): ready now; reloads and the stop announced; the watchdog fed while the e-stop's
  // thread answers.
  notify_service_manager("READY=1\nSTATUS=serving on port " + std::to_string(port));
  std::optional<ServiceWatchdog> watchdog;
  if (const auto interval = service_watchdog_interval())
    watchdog.emplace(*interval, [&kernel](std::chrono::milliseconds within) { return kernel.stop_path_responsive(within); });
  int signal = 0;
  while (sigwait(&signals, &signal) == 0 && signal == SIGHUP) {
    notify_service_manager("RELOADING=1");
    kernel.reload(options.config);
    notify_service_manager("READY=1");
  }
  notify_service_manager("STOPPING=1");
  watchdog.reset();
  rcand::logger("kernel")->info("signal {}: shutting down", signal);
  // The motors halt first and within the stop deadline; a plugin stuck in its shutdown hook must not keep the
  // process alive after that (systemd would wait for TimeoutStopSec, then SIGKILL).
  std::thread([] {
    std::this_thread::sleep_for(kShutdownGrace);
    rcand::logger("kernel")->error("shutdown still blocked by plugin code after {} s; exiting now", kShutdownGrace.count());
    std::_Exit(1);
  }).detach();
  kernel.shutdown();
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  if (auto done = parse_arguments(std::vector<std::string>(argv + 1, argv + argc), options)) return *done;
  configure_logging("info");
  config::set_default_load_options(config::LoadOptions{options.strict});
  if (options.check_plugins) return check_plugins(options);
  if (options.describe) return describe(options);

  // Signals are taken synchronously by the main thread; every thread started later inherits the mask.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGHUP);  // config reload
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  std::signal(SIGPIPE, SIG_IGN);

  raise_open_files_limit();
  std::vector<std::string> protocols;  // the drivers', for advice on one no plugin serves
  try {
    // --as-user: the files are also judged as trusted or not for that user, as the service running as it would.
    std::optional<UserIdentity> user;
    if (options.check_config && !options.as_user.empty() && !(user = lookup_user(options.as_user)))
      return usage_error("--as-user: no user named '" + options.as_user + "'");
    config::LoadOptions load_options = config::default_load_options();
    if (user) load_options.user = user->uid;
    config::LoadedConfig loaded = config::load_robot_config(options.config, load_options);
    for (const auto& driver : loaded.config.drivers) protocols.push_back(driver.protocol);
    print_warnings(loaded);
    configure_logging(loaded.config.runtime.log_level);
    const auto fragments = loaded.config.fragment_files;
    for (const auto& fragment : fragments) logger("kernel")->info("config: merged the conf.d fragment {}", fragment.string());
    if (!options.check_config) return serve(options, std::move(loaded), signals);
    if (user) {
      auto plugin_paths = options.plugin_paths.empty() ? loaded.config.runtime.plugin_paths : options.plugin_paths;
      if (plugin_paths.empty()) plugin_paths = default_plugin_paths();
      const auto problems = config::config_access_problems(loaded.config, plugin_paths, *user);
      for (const auto& problem : problems) std::cerr << "rcand: --as-user " << options.as_user << ": " << problem << "\n";
      if (!problems.empty()) return 1;
    }
    // Everything short of serving, and nothing it would touch: plugins checked against the config, none started.
    const auto report = Kernel::check(std::move(loaded.config), kernel_options(options));
    std::cout << options.config << ": OK (capabilities: ";
    for (std::size_t i = 0; i < report.capabilities.size(); ++i) std::cout << (i ? ", " : "") << report.capabilities[i];
    std::cout << ")\n";
    for (const auto& fragment : fragments) std::cout << "  merged " << fragment.string() << "\n";
    for (const auto& line : report.fail_safes) std::cout << "  fail-safe of " << line << "\n";
    return 0;
  } catch (const yaml::ConfigError& e) {
    for (const auto& diagnostic : e.diagnostics())
      std::cerr << config::with_protocol_advice(diagnostic, protocols).format() << "\n";
    std::cerr << "rcand: configuration invalid; not started\n";
    return 1;
  } catch (const StartupError& e) {
    std::cerr << "rcand: " << e.what() << "\n";
    return 1;
  }
}
