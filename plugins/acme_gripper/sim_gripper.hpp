// Driver protocol "acme_gripper_sim": a gripper that moves instantly and can pretend to hold an object.
#pragma once

#include <cstdint>
#include <mutex>

#include "gripper.hpp"

namespace acme::gripper {

class SimGripper final : public Gripper {
 public:
  // object_size in [0, 1]: the jaws stop at this opening when closing past it (0 = nothing to hold).
  explicit SimGripper(double object_size);
  void set_opening(double opening) override;
  double opening() const override;
  bool holding() const override;
  void halt() noexcept override;  // the sim moves instantly, so halting only freezes and counts
  nlohmann::json status() const override;

 private:
  const double object_size_;
  mutable std::mutex mutex_;  // this driver's state only
  double opening_ = 1.0;      // starts open
  bool holding_ = false;
  std::uint64_t commands_ = 0;
  std::uint64_t halts_ = 0;
};

}  // namespace acme::gripper
