// rcand: the daemon. Parses the command line, loads the config, runs the kernel until SIGINT/SIGTERM; SIGHUP
// reloads the config file (Kernel::reload).
#include <pthread.h>
#include <sys/resource.h>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "kernel/config/robot_config.hpp"
#include "kernel/kernel.hpp"
#include "kernel/service.hpp"
#include "libs/base/logging.hpp"
#include "rcand/sdk/abi.h"

namespace {

using namespace rcand;
using namespace rcand::kernel;

constexpr const char* kUsage = R"(usage: rcand [--config FILE] [--plugin-path DIR]... [--port N]
       rcand --check-config FILE
       rcand --check-plugins [--config FILE] [--plugin-path DIR]...
       rcand --version

  --config FILE        robot config (.rcan.yaml); default /etc/rcand/robot.rcan.yaml
  --plugin-path DIR    load plugins from DIR instead of runtime.plugin_paths (repeatable)
  --port N             listen on port N instead of the configured one (0: any free port)
  --check-config FILE  validate FILE (schema, capabilities against installed plugins) and exit
  --check-plugins      open every installed plugin, print the table, exit 1 if any failed

On start, rcand prints one line "rcand: listening on http://ADDRESS:PORT" on stdout once it serves.
)";

constexpr std::chrono::seconds kShutdownGrace{5};

struct Options {
  std::string config = "/etc/rcand/robot.rcan.yaml";
  std::vector<std::filesystem::path> plugin_paths;
  std::optional<std::uint16_t> port;
  bool check_config = false, check_plugins = false;
};

int usage_error(const std::string& message) {
  std::cerr << "rcand: " << message << "\n" << kUsage;
  return 2;
}

void print_warnings(const LoadedConfig& loaded) {
  for (const auto& warning : loaded.warnings) std::cerr << warning.format() << "\n";
}

KernelOptions kernel_options(const Options& options) {
  KernelOptions result;
  result.services = linked_services();  // the optional services linked into rcand (services/)
  if (!options.plugin_paths.empty()) result.plugin_paths = options.plugin_paths;
  result.port = options.port;
  return result;
}

int check_plugins(const Options& options) {
  std::vector<std::filesystem::path> paths = options.plugin_paths;
  if (paths.empty()) {
    try {
      paths = load_robot_config(options.config).config.runtime.plugin_paths;
      if (paths.empty()) paths = default_plugin_paths();
    } catch (const ConfigError&) {
      paths = default_plugin_paths();
    }
  }
  PluginHost host;
  host.scan(paths);
  std::set<std::string> capabilities, protocols;
  for (const auto& record : host.records()) {
    if (!record->manifest) continue;
    for (const auto& item : record->manifest->provides) (item.kind == "driver" ? protocols : capabilities).insert(item.name);
  }
  host.load_needed(capabilities, protocols);
  std::cout << host.format_table();
  return host.any_failed() ? 1 : 0;
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
    } else {
      return usage_error("unknown argument '" + arg + "'");
    }
  }

  return std::nullopt;
}

int serve(const Options& options, LoadedConfig loaded, sigset_t& signals) {
  const std::string address = loaded.config.runtime.listen_address;
  Kernel kernel(std::move(loaded.config), kernel_options(options));
  const auto port = kernel.start();
  std::cout << "rcand: listening on http://" << address << ":" << port << std::endl;
  int signal = 0;
  while (sigwait(&signals, &signal) == 0 && signal == SIGHUP) kernel.reload(options.config);
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
  if (options.check_plugins) return check_plugins(options);

  // Signals are taken synchronously by the main thread; every thread started later inherits the mask.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGHUP);  // config reload
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  std::signal(SIGPIPE, SIG_IGN);

  raise_open_files_limit();
  try {
    LoadedConfig loaded = load_robot_config(options.config);
    print_warnings(loaded);
    configure_logging(loaded.config.runtime.log_level);
    if (!options.check_config) return serve(options, std::move(loaded), signals);
    // Everything short of serving: plugins are scanned and capabilities checked against them.
    Kernel kernel(std::move(loaded.config), kernel_options(options));
    std::cout << options.config << ": OK (capabilities: ";
    const auto& names = kernel.registry().names();
    for (std::size_t i = 0; i < names.size(); ++i) std::cout << (i ? ", " : "") << names[i];
    std::cout << ")\n";
    return 0;
  } catch (const ConfigError& e) {
    for (const auto& diagnostic : e.diagnostics()) std::cerr << diagnostic.format() << "\n";
    std::cerr << "rcand: configuration invalid; not started\n";
    return 1;
  } catch (const StartupError& e) {
    std::cerr << "rcand: " << e.what() << "\n";
    return 1;
  }
}
