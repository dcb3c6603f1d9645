// swarm.yaml as now (§15.2), for the services that reach the swarm: broadcasts and the swarm table, R2R's relay and
// WebSocket dialing. Empty until the swarm-broadcast service loads runtime.swarm_file; each SIGHUP reload swaps it
// whole. The registries it replaced are kept for the life of the process (one per reload): a request in flight may
// still read one.
#pragma once

#include <atomic>
#include <memory>
#include <mutex>
#include <vector>

#include "libs/swarm/swarm_registry.hpp"

namespace rcand::swarm {

class LiveRegistry {
 public:
  LiveRegistry();
  const SwarmRegistry& now() const noexcept { return *now_.load(std::memory_order_acquire); }
  void replace(SwarmRegistry next);

 private:
  std::mutex mutex_;  // kept_
  std::vector<std::unique_ptr<const SwarmRegistry>> kept_;
  std::atomic<const SwarmRegistry*> now_;
};

}  // namespace rcand::swarm
