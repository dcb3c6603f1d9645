// Slots that many callers share: a WebSocket endpoint's connections, the robot's streamed answers. At most `capacity`
// at once, of which the last `reserved` only for holders that may use them; at most `per_principal` for one principal
// and `per_address` for one client address. So one caller cannot take every slot, nor can one host holding many
// credentials, and the reserved ones stay free for the robot's owners (docs/protocol.md §7.17). A claim is counted at
// once, under one brief lock (concurrent claims cannot all slip under a limit), and given back when the last copy of
// its slot handle is destroyed. Any thread.
#pragma once

#include <cstddef>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

namespace rcand {

struct SlotLimits {
  static constexpr std::size_t kUnlimited = std::numeric_limits<std::size_t>::max();
  std::size_t capacity = kUnlimited;
  std::size_t reserved = 0;  // of capacity
  std::size_t per_principal = kUnlimited;
  std::size_t per_address = kUnlimited;
};

// Who claims a slot. An empty principal or address is not counted against that cap.
struct SlotHolder {
  std::string principal;
  std::string address;
  bool may_use_reserved = false;
};

class SlotTable {
 public:
  enum class Refusal { Full, PrincipalCap, AddressCap, Reserved };
  struct Claim {
    std::shared_ptr<void> slot;      // set: the slot is held until every copy is destroyed
    std::optional<Refusal> refusal;  // set when `slot` is not
    std::size_t held = 0;            // refused by a cap: what that principal or address holds already
  };

  explicit SlotTable(SlotLimits limits);
  // The checks in order: capacity, the principal's cap, the address's cap, the reserved slots.
  Claim claim(const SlotHolder& holder);
  std::size_t in_use() const;
  const SlotLimits& limits() const noexcept { return limits_; }

 private:
  struct Counts;
  struct Held;
  const SlotLimits limits_;
  std::shared_ptr<Counts> counts_;  // shared with every slot, which may outlive the table
};

}  // namespace rcand
