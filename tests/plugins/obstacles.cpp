// A test double for the vision plugin's depth zones: a non-actuating driver (protocol org.rcand.test.obstacles)
// implementing sdk::ObstacleSource. It reports `nearest_cm` on every zone, and `then_cm` from read number
// `after_reads` on, so a test can put an obstacle in front of a running nav job without any timing of its own.
#include <rcand/sdk/export.hpp>
#include <rcand/sdk/interfaces/obstacle_source.hpp>
#include <rcand/sdk/plugin.hpp>

#include <atomic>
#include <chrono>

namespace {

class FakeObstacles final : public rcand::sdk::Driver, public rcand::sdk::ObstacleSource {
 public:
  explicit FakeObstacles(rcand::sdk::PluginContext& ctx)
      : clock_(ctx.clock()),
        nearest_cm_(ctx.config().get_or<double>("nearest_cm", 500.0)),
        then_cm_(ctx.config().get_or<double>("then_cm", nearest_cm_)),
        after_reads_(ctx.config().get_or<long long>("after_reads", 0)),
        available_(ctx.config().get_or<bool>("available", true)) {}

  rcand::sdk::ObstacleReading obstacles() const noexcept override {
    const long long n = ++reads_;
    const double cm = after_reads_ > 0 && n >= after_reads_ ? then_cm_ : nearest_cm_;
    return {available_, cm, cm, cm, cm, clock_.wall_ms()};
  }
  nlohmann::json status() const override { return {{"reads", reads_.load()}}; }

 private:
  const rcand::sdk::Clock& clock_;
  const double nearest_cm_, then_cm_;
  const long long after_reads_;
  const bool available_;
  mutable std::atomic<long long> reads_{0};
};

void register_obstacles(rcand::sdk::Registrar& registrar) {
  registrar.add_driver({"org.rcand.test.obstacles", false, ""},
                       [](rcand::sdk::PluginContext& ctx) { return std::make_unique<FakeObstacles>(ctx); });
}

}  // namespace

RCAND_PLUGIN("org.rcand.test.obstacles", "1.0.0", register_obstacles)
