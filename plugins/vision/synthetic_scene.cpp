#include "synthetic_scene.hpp"

#include <cmath>
#include <numbers>

namespace rcand::plugins::vision {

cv::Mat SyntheticScene::render(int width, int height, double seconds) const {
  // A copy of the far wall, made once: filling 16-bit pixels with a scalar each frame took 8x as long as this copy
  // and was a quarter of the robot's CPU at rest.
  cv::Mat wall;  // a reference to the kept frame (never written once made): the copy runs without the lock
  {
    std::lock_guard lock(mutex_);
    if (wall_.rows != height || wall_.cols != width) wall_ = cv::Mat(height, width, CV_16UC1, cv::Scalar(3500));
    wall = wall_;
  }
  cv::Mat depth = wall.clone();
  struct Swing {
    double near_m, far_m, period_s;
  };
  // Each at its own period, so the zones differ; the centre one comes nearest.
  static constexpr std::array<Swing, 3> kObjects{{{1.4, 3.0, 9.0}, {kNearestSwing_m, 3.0, 12.0}, {1.6, 3.2, 7.0}}};
  for (int i = 0; i < 3; ++i) {
    const auto& o = kObjects[static_cast<std::size_t>(i)];
    const double phase = 0.5 + 0.5 * std::cos(2 * std::numbers::pi * seconds / o.period_s);  // 1 far .. 0 near
    const double metres = o.near_m + (o.far_m - o.near_m) * phase;
    const cv::Rect box(i * width / 3 + width / 12, height / 3, width / 6, height / 3);
    depth(box).setTo(cv::Scalar(metres * 1000.0));
  }
  const auto placed = this->placed();
  for (int i = 0; i < 3; ++i) {
    const auto& metres = placed[static_cast<std::size_t>(i)];
    if (!metres) continue;
    // Wider and taller than the moving object in the same third, so it hides it.
    const cv::Rect box(i * width / 3 + width / 24, height / 4, width / 4, height / 2);
    depth(box).setTo(cv::Scalar(*metres * 1000.0));
  }
  return depth;
}

void SyntheticScene::place(int zone, std::optional<double> metres) {
  std::lock_guard lock(mutex_);
  placed_.at(static_cast<std::size_t>(zone)) = metres;
}

std::array<std::optional<double>, 3> SyntheticScene::placed() const {
  std::lock_guard lock(mutex_);
  return placed_;
}

}  // namespace rcand::plugins::vision
