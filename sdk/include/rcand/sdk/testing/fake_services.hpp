// The service directory of the fake host (rcand/sdk/testing/fake_host.hpp), with the kernel's rules
// (rcand/sdk/services.hpp): one provider per service id, an offer refused (false, logged) when the id is empty, the
// object null or the id taken, an instance's offers withdrawn before its shutdown, and a failed instance's offers
// found as null. Offers and finds may come from any thread.
#pragma once

#include <map>
#include <mutex>
#include <string>
#include <string_view>

#include "rcand/sdk/logger.hpp"

namespace rcand::sdk::testing {

class FakeServiceDirectory {
 public:
  explicit FakeServiceDirectory(Logger& log) : log_(log) {}
  FakeServiceDirectory(const FakeServiceDirectory&) = delete;
  FakeServiceDirectory& operator=(const FakeServiceDirectory&) = delete;

  // `owner`: the offering instance (driver id or capability name), "" for the test. Not owned.
  bool offer(const std::string& owner, std::string_view id, const void* service) noexcept {
    try {
      const std::string who = owner.empty() ? std::string("the test") : "instance '" + owner + "'";
      if (id.empty() || !service) {
        log_.error(who, ": offer of service '", id, "' refused: ", id.empty() ? "empty id" : "null object");
        return false;
      }
      std::lock_guard lock(mutex_);
      if (!offers_.emplace(std::string(id), Offer{service, owner}).second) {
        log_.error(who, ": offer of service '", id, "' refused: already offered (one provider per service)");
        return false;
      }
      return true;
    } catch (...) {
      return false;
    }
  }
  // The test's own offer of `id`, replacing any earlier one, the test's or an instance's (null: none).
  void replace(std::string_view id, const void* service) noexcept {
    try {
      std::lock_guard lock(mutex_);
      if (const auto it = offers_.find(id); it != offers_.end()) offers_.erase(it);
      if (service) offers_.emplace(std::string(id), Offer{service, ""});
    } catch (...) {
    }
  }
  void withdraw(const std::string& owner) noexcept {
    std::lock_guard lock(mutex_);
    std::erase_if(offers_, [&owner](const auto& entry) { return entry.second.owner == owner; });
  }
  // The object offered as `id`; null when nothing offers it or `failed(owner)` says its instance failed.
  template <class Failed> const void* find(std::string_view id, const Failed& failed) const noexcept {
    std::lock_guard lock(mutex_);
    const auto it = offers_.find(id);
    if (it == offers_.end() || failed(it->second.owner)) return nullptr;
    return it->second.object;
  }

 private:
  struct Offer {
    const void* object = nullptr;
    std::string owner;  // the offering instance; "" for the test
  };
  Logger& log_;
  mutable std::mutex mutex_;
  std::map<std::string, Offer, std::less<>> offers_;
};

}  // namespace rcand::sdk::testing
