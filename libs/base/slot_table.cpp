#include "libs/base/slot_table.hpp"

#include <algorithm>

namespace rcand {
namespace {

std::size_t held_by(const std::map<std::string, std::size_t>& counts, const std::string& key) {
  const auto it = key.empty() ? counts.end() : counts.find(key);
  return it == counts.end() ? 0 : it->second;
}

void give_back(std::map<std::string, std::size_t>& counts, const std::string& key) {
  if (key.empty()) return;
  if (auto it = counts.find(key); it != counts.end() && --it->second == 0) counts.erase(it);
}

}  // namespace

struct SlotTable::Counts {
  std::mutex mutex;
  std::size_t in_use = 0;
  std::map<std::string, std::size_t> by_principal, by_address;
};

// One held slot: what it counted against, given back when destroyed.
struct SlotTable::Held {
  std::shared_ptr<Counts> counts;  // null until counted
  SlotHolder holder;
  explicit Held(SlotHolder who) : holder(std::move(who)) {}
  Held(const Held&) = delete;
  Held& operator=(const Held&) = delete;
  ~Held() {
    if (!counts) return;
    std::lock_guard lock(counts->mutex);
    --counts->in_use;
    give_back(counts->by_principal, holder.principal);
    give_back(counts->by_address, holder.address);
  }
};

SlotTable::SlotTable(SlotLimits limits) : limits_(limits), counts_(std::make_shared<Counts>()) {}

SlotTable::Claim SlotTable::claim(const SlotHolder& holder) {
  auto slot = std::make_shared<Held>(holder);
  std::lock_guard lock(counts_->mutex);
  const std::size_t open_to_all = limits_.capacity - std::min(limits_.reserved, limits_.capacity);
  const std::size_t by_principal = held_by(counts_->by_principal, holder.principal);
  const std::size_t by_address = held_by(counts_->by_address, holder.address);
  Claim claim;
  if (counts_->in_use >= limits_.capacity) {
    claim.refusal = Refusal::Full;
  } else if (!holder.principal.empty() && by_principal >= limits_.per_principal) {
    claim.refusal = Refusal::PrincipalCap;
    claim.held = by_principal;
  } else if (!holder.address.empty() && by_address >= limits_.per_address) {
    claim.refusal = Refusal::AddressCap;
    claim.held = by_address;
  } else if (!holder.may_use_reserved && counts_->in_use >= open_to_all) {
    claim.refusal = Refusal::Reserved;
  }
  if (claim.refusal) return claim;  // `slot` was never counted: its destructor gives nothing back
  ++counts_->in_use;
  if (!holder.principal.empty()) ++counts_->by_principal[holder.principal];
  if (!holder.address.empty()) ++counts_->by_address[holder.address];
  slot->counts = counts_;
  claim.slot = std::move(slot);
  return claim;
}

std::size_t SlotTable::in_use() const {
  std::lock_guard lock(counts_->mutex);
  return counts_->in_use;
}

}  // namespace rcand
