// An actuating differential_drive driver (protocol org.rcand.test.fake_drive) that records the last command.
#include <atomic>
#include <mutex>

#include "fixture.hpp"

namespace {

class FakeDrive final : public rcand::sdk::DifferentialDrive {
 public:
  void set_wheel_speeds(double left, double right) override {
    std::lock_guard lock(mutex_);
    left_ = left, right_ = right;
  }
  void halt() noexcept override {
    std::lock_guard lock(mutex_);
    left_ = right_ = 0.0;
    ++halts_;
  }
  nlohmann::json status() const override {
    std::lock_guard lock(mutex_);
    return {{"left", left_}, {"right", right_}, {"halts", halts_}};
  }

 private:
  mutable std::mutex mutex_;
  double left_ = 0.0, right_ = 0.0;
  int halts_ = 0;
};

void register_driver(rcand::sdk::Registrar& registrar) {
  registrar.add_driver({"org.rcand.test.fake_drive", true, std::string(rcand::sdk::DifferentialDrive::kInterface)},
                       [](rcand::sdk::PluginContext&) { return std::make_unique<FakeDrive>(); });
}

}  // namespace

RCAND_PLUGIN("org.rcand.test.driver", "1.0.0", register_driver)
