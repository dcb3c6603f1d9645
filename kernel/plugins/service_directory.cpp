#include "kernel/plugins/service_directory.hpp"

#include "libs/base/logging.hpp"

namespace rcand::kernel {

// Copy on write: offers are a handful, made at startup and withdrawn at shutdown, while finds may come from any
// plugin thread at any rate, so a find only loads the current list.
bool ServiceDirectory::offer_service(std::string_view id, const void* service, const void* owner, const std::string& who,
                                     const InstanceHealth* health) noexcept {
  try {
    auto log = logger("kernel.services");
    if (id.empty() || service == nullptr) {
      log->error("{}: offer of service '{}' refused: {}", who, id, id.empty() ? "empty id" : "null object");
      return false;
    }
    std::lock_guard lock(mutex_);
    const auto current = offers_.load();
    for (const auto& offer : *current)
      if (offer.id == id) {
        log->error("{}: offer of service '{}' refused: already offered (one provider per service)", who, id);
        return false;
      }
    auto next = std::make_shared<Offers>(*current);
    next->push_back({std::string(id), service, owner, health});
    offers_.store(std::move(next));
    log->info("{} offers service '{}'", who, id);
    return true;
  } catch (...) {  // no memory: the offer did not happen
    return false;
  }
}

const void* ServiceDirectory::service(std::string_view id) const noexcept {
  const auto current = offers_.load();
  for (const auto& offer : *current)
    if (offer.id == id) return offer.health != nullptr && offer.health->failed() ? nullptr : offer.service;
  return nullptr;
}

void ServiceDirectory::withdraw(const void* owner) noexcept {
  try {
    std::lock_guard lock(mutex_);
    const auto current = offers_.load();
    auto next = std::make_shared<Offers>();
    for (const auto& offer : *current)
      if (offer.owner != owner) next->push_back(offer);
    if (next->size() != current->size()) offers_.store(std::move(next));
  } catch (...) {  // no memory for the copy: mark nothing; the instance's health still hides its offers once failed
  }
}

}  // namespace rcand::kernel
