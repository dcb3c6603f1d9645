// Obstacle zones (§12, docs/protocol.md §7 GET /api/depth/obstacles) as a plugin-to-plugin interface: the vision plugin's
// depth pipeline (or a test double) implements it on a driver or capability object; the kernel finds it and hands
// it to every plugin through PluginContext::obstacles(), so nav can check the zones before and during a job.
#pragma once

#include <cstdint>
#include <optional>

#include "rcand/sdk/export.hpp"

namespace rcand::sdk {

// One reading. Each zone is the minimum depth over a vertical third of the image, in centimetres.
struct ObstacleReading {
  bool available = false;  // false: no fresh depth data (camera down, not yet warmed up); the fields mean nothing
  double left_cm = 0.0;
  double center_cm = 0.0;
  double right_cm = 0.0;
  double nearest_cm = 0.0;       // min of the three zones
  std::int64_t timestamp_ms = 0;  // Unix ms of the frame it came from
};

class RCAND_INTERFACE ObstacleSource {
 public:
  virtual ~ObstacleSource() = default;
  // Any thread, thread-safe, never blocks (returns the latest reading it has). Must not throw.
  virtual ObstacleReading obstacles() const noexcept = 0;
};

}  // namespace rcand::sdk
