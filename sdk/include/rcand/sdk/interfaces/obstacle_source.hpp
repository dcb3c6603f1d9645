// Obstacle zones (§12, docs/protocol.md §7 GET /api/depth/obstacles) as a service (rcand/sdk/services.hpp): the
// vision plugin's depth pipeline (or a test double) offers it, and nav finds it to check the zones before and during
// a job. For plugins built before ABI 1.2, the kernel also offers the first driver or capability object that
// implements it (found with dynamic_cast), and PluginContext::obstacles() is find<ObstacleSource>().
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

#include "rcand/sdk/export.hpp"
#include "rcand/sdk/services.hpp"

namespace rcand::sdk {

// One reading. Each zone is the minimum depth over a vertical third of the image, in centimetres.
struct ObstacleReading {
  bool available = false;  // false: no fresh depth data (camera down, not yet warmed up); the fields mean nothing
  double left_cm = 0.0;
  double center_cm = 0.0;
  double right_cm = 0.0;
  double nearest_cm = 0.0;        // min of the three zones
  std::int64_t timestamp_ms = 0;  // Unix ms of the frame it came from
};

class RCAND_INTERFACE ObstacleSource {
 public:
  static constexpr std::string_view kServiceId = "rcand.obstacle_source/1";
  virtual ~ObstacleSource() = default;
  // Any thread, thread-safe, never blocks (returns the latest reading it has). Must not throw.
  virtual ObstacleReading obstacles() const noexcept = 0;
};

}  // namespace rcand::sdk
