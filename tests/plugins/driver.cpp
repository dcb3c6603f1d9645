// An actuating differential_drive driver (protocol org.rcand.test.fake_drive) that records the last command. Built a
// second time as a vendor's plugin for a protocol rcand reads as an alias (vendor_l298n/: com.acme.l298n, "l298n").
#ifndef RCAND_TEST_DRIVER_ID
#define RCAND_TEST_DRIVER_ID "org.rcand.test.driver"
#define RCAND_TEST_DRIVER_PROTOCOL "org.rcand.test.fake_drive"
#endif
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
  registrar.add_driver({RCAND_TEST_DRIVER_PROTOCOL, true, std::string(rcand::sdk::DifferentialDrive::kInterface)},
                       [](rcand::sdk::PluginContext&) { return std::make_unique<FakeDrive>(); });
}

}  // namespace

RCAND_PLUGIN(RCAND_TEST_DRIVER_ID, "1.0.0", register_driver)
