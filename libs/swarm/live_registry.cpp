#include "libs/swarm/live_registry.hpp"

#include <utility>

namespace rcand::swarm {

LiveRegistry::LiveRegistry() {
  kept_.push_back(std::make_unique<const SwarmRegistry>());
  now_.store(kept_.back().get());
}

void LiveRegistry::replace(SwarmRegistry next) {
  std::lock_guard lock(mutex_);
  kept_.push_back(std::make_unique<const SwarmRegistry>(std::move(next)));
  now_.store(kept_.back().get(), std::memory_order_release);
}

}  // namespace rcand::swarm
