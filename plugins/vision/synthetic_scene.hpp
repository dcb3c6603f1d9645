// The synthetic depth scene (camera.depth: synthetic): what the simulated robot's depth camera sees. A wall at
// 3.5 m and one object per third of the image that approaches and recedes, never nearer than 1 m, so the bundled sim
// robot with an obstacle minimum (config/) drives the README's examples without an obstacle stop; an obstacle stop is
// asked for by placing an object in a zone (POST /api/depth/sim_obstacle, sim only), which stays until removed.
#pragma once

#include <opencv2/core.hpp>

#include <array>
#include <mutex>
#include <optional>
#include <string_view>

namespace rcand::plugins::vision {

class SyntheticScene {
 public:
  static constexpr std::array<std::string_view, 3> kZones{"left", "center", "right"};
  static constexpr double kNearestSwing_m = 1.0;  // the moving objects never come nearer

  // The scene at `seconds` since it started: depth in millimetres (CV_16UC1), placed objects in front.
  cv::Mat render(int width, int height, double seconds) const;
  // Places an object `metres` away filling most of `zone` (0 left, 1 centre, 2 right), or removes it (nullopt).
  // Any thread.
  void place(int zone, std::optional<double> metres);
  std::array<std::optional<double>, 3> placed() const;

 private:
  mutable std::mutex mutex_;
  std::array<std::optional<double>, 3> placed_{};
  mutable cv::Mat wall_;  // the empty scene at the size last rendered
};

}  // namespace rcand::plugins::vision
