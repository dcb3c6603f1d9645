// A read-only view of the kernel's latched e-stop. Plugins cannot latch or clear it except through
// request_estop(), which latches exactly as POST /api/stop does (used by obstacle checks).
#pragma once

#include <chrono>
#include <functional>
#include <string>

#include "rcand/sdk/export.hpp"

namespace rcand::sdk {

class RCAND_INTERFACE EstopView {
 public:
  virtual ~EstopView() = default;
  // Any thread, never blocks (one atomic load).
  virtual bool latched() const noexcept = 0;
  // Any thread. Sleeps up to `duration`; returns early with false as soon as the e-stop latches
  // (true when the full duration passed unlatched). Blocks: call only from a worker, never from a handler
  // that must answer quickly.
  virtual bool sleep_unless_latched(std::chrono::microseconds duration) const = 0;
  // Any thread. Latches the e-stop with `reason`; returns after every actuating driver confirmed halt().
  virtual void request_estop(const std::string& reason) noexcept = 0;
};

}  // namespace rcand::sdk
