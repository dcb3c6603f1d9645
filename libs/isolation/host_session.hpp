// rcand-plugin-host's life (services/plugin_host): the start message, the plugin opened and its capability started,
// then every message of rcand served until it says shutdown or its channel ends. The channel's reader runs from the
// start (rcand's answers to what the capability asks during its start() arrive there). Requests run one at a time on
// the capability's worker, as in rcand; on_estop() and status() on threads of their own, so neither waits behind a
// request; the heartbeat is answered from the reader, so a request that runs long does not end the host.
#pragma once

#include <nlohmann/json.hpp>

#include <functional>
#include <memory>

#include "libs/isolation/channel.hpp"
#include "libs/isolation/frame_ring.hpp"
#include "rcand/sdk/registrar.hpp"

namespace rcand::isolation {

// The plugin opened for the start message: its capability's factory, the descriptor's ABI minor, and what keeps the
// library loaded. A loader throws std::exception with the reason (the loader's own checks refused it).
struct LoadedCapability {
  sdk::CapabilityFactory factory;
  int abi_minor = 0;
  std::shared_ptr<void> keep;
};
using CapabilityLoader = std::function<LoadedCapability(const nlohmann::json& start)>;
// Enters the host's sandbox for the start message's needs and answers what it enforces (shown in the capability's
// status); throws with the reason when it cannot. Called before the session starts any thread: a Landlock ruleset
// binds the calling thread and the threads it starts afterwards, not those already running.
using SandboxEntry = std::function<nlohmann::json(const nlohmann::json& start)>;

// The process's exit status: 0 after rcand's shutdown, 2 without a start message, 3 when the capability did not
// start (rcand got the reason first). `ring`: the frame ring rcand passed (null: frames go inline). `sandbox`: none in
// the unit tests, which run the session in their own process.
int run_host(Channel& channel, FrameRing* ring, const CapabilityLoader& load, const SandboxEntry& sandbox = {});

}  // namespace rcand::isolation
