// The services plugin instances offer each other (sdk::PluginContext::offer_service and service(); the rules are in
// rcand/sdk/services.hpp). Ids are compared, never types: the object crosses as const void*. Also what rcand's
// in-tree services and the status board find plugin services through (sdk::find<T>(directory)).
#pragma once

#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "kernel/safety/instance_health.hpp"

namespace rcand::kernel {

class ServiceDirectory {
 public:
  // Any thread, a brief lock. `owner` identifies the offering instance for withdraw(); `who` names it in logs; an
  // offer whose `health` is failed is no longer found. Refused (logged, false): an empty id, a null object, or an id
  // already offered.
  bool offer_service(std::string_view id, const void* service, const void* owner, const std::string& who,
                     const InstanceHealth* health) noexcept;
  // Any thread, lock-free: the object offered as `id` by an instance not failed, or null.
  const void* service(std::string_view id) const noexcept;
  // Any thread: every offer `owner` made is withdrawn (the instance is stopping). A find that already returned one
  // of them may still be using it; the owner keeps the object alive until it is destroyed.
  void withdraw(const void* owner) noexcept;

 private:
  struct Offer {
    std::string id;
    const void* service;
    const void* owner;
    const InstanceHealth* health;
  };
  using Offers = std::vector<Offer>;
  std::mutex mutex_;  // serializes offers and withdrawals; finds read the published list without it
  std::atomic<std::shared_ptr<const Offers>> offers_{std::make_shared<const Offers>()};
};

}  // namespace rcand::kernel
