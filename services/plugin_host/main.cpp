// rcand-plugin-host: the process an isolated capability runs in (libs/isolation/host_session.hpp). rcand starts it
// with its end of the channel on descriptor 3 and the frame ring on 4; it opens the plugin rcand chose through rcand's own plugin
// host (the manifest, the descriptor and the registration checked as in rcand), runs the capability, and ends with rcand.
#include <sys/prctl.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "kernel/plugins/plugin_host.hpp"
#include "libs/base/logging.hpp"
#include "libs/isolation/host_sandbox.hpp"
#include "libs/isolation/host_session.hpp"

namespace rcand::services {

namespace {

// Entered before the session starts a thread, and before the plugin is opened: its static initialisers already run
// inside it.
nlohmann::json sandbox(const nlohmann::json& start) {
  return isolation::enter_host_sandbox(::getppid(), start.value("sandbox", nlohmann::json::object()));
}

isolation::LoadedCapability load(const nlohmann::json& start) {
  auto host = std::make_shared<kernel::PluginHost>();
  std::vector<std::filesystem::path> paths;
  for (const auto& path : start.at("plugin_paths")) paths.emplace_back(path.get<std::string>());
  const std::string id = start.at("plugin").get<std::string>(), capability = start.at("capability").get<std::string>();
  host->scan(paths);
  host->load_needed({capability}, {});
  const kernel::PluginRecord* record = host->find(id);
  if (record == nullptr) throw std::runtime_error("plugin " + id + " is not installed in rcand's plugin path");
  if (record->state != kernel::PluginState::Loaded)
    throw std::runtime_error("plugin " + id + " is " + std::string(kernel::to_string(record->state)) + ": " + record->reason);
  for (const auto& registered : record->capabilities)
    if (registered.info.name == capability) return {registered.factory, record->abi_minor, host};
  throw std::runtime_error("plugin " + id + " registers no capability " + capability);
}

}  // namespace

}  // namespace rcand::services

int main(int argc, char** argv) {
  if (argc != 3 || std::string_view(argv[1]) != "--parent") {
    std::fprintf(stderr, "usage: rcand-plugin-host --parent PID (rcand starts it, its channel on descriptor 3)\n");
    return 2;
  }
  ::prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (std::to_string(::getppid()) != argv[2]) return 1;  // rcand ended before the line above took effect
  rcand::configure_logging("info");
  rcand::isolation::Channel channel(3);
  std::unique_ptr<rcand::isolation::FrameRing> ring;
  try {
    ring = rcand::isolation::FrameRing::attach(4);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rcand-plugin-host: %s: frames go inline\n", e.what());
  }
  return rcand::isolation::run_host(channel, ring.get(), rcand::services::load, rcand::services::sandbox);
}
