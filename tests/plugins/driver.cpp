// An actuating differential_drive driver (protocol org.rcand.test.fake_drive) that records the last command, and
// with setting witness_file appends "constructed by pid N" and "halted by pid N" lines to that file: what a process
// did to the robot's hardware, seen from outside it. Built a second time as a vendor's plugin for a protocol rcand
// reads as an alias (vendor_l298n/: com.acme.l298n, "l298n").
#ifndef RCAND_TEST_DRIVER_ID
#define RCAND_TEST_DRIVER_ID "org.rcand.test.driver"
#define RCAND_TEST_DRIVER_PROTOCOL "org.rcand.test.fake_drive"
#endif
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <mutex>
#include <string>
#include <utility>

#include "fixture.hpp"

namespace {

void witness(const std::string& file, const char* what) noexcept {
  if (file.empty()) return;
  if (std::FILE* out = std::fopen(file.c_str(), "a")) {
    std::fprintf(out, "%s by pid %d\n", what, static_cast<int>(::getpid()));
    std::fclose(out);
  }
}

class FakeDrive final : public rcand::sdk::DifferentialDrive {
 public:
  explicit FakeDrive(std::string witness_file) : witness_file_(std::move(witness_file)) { witness(witness_file_, "constructed"); }
  void set_wheel_speeds(double left, double right) override {
    std::lock_guard lock(mutex_);
    left_ = left, right_ = right;
  }
  void halt() noexcept override {
    std::lock_guard lock(mutex_);
    left_ = right_ = 0.0;
    ++halts_;
    witness(witness_file_, "halted");
  }
  nlohmann::json status() const override {
    std::lock_guard lock(mutex_);
    return {{"left", left_}, {"right", right_}, {"halts", halts_}};
  }

 private:
  const std::string witness_file_;
  mutable std::mutex mutex_;
  double left_ = 0.0, right_ = 0.0;
  int halts_ = 0;
};

void register_driver(rcand::sdk::Registrar& registrar) {
  registrar.add_driver({RCAND_TEST_DRIVER_PROTOCOL, true, std::string(rcand::sdk::DifferentialDrive::kInterface)},
                       [](rcand::sdk::PluginContext& context) {
                         return std::make_unique<FakeDrive>(context.config().get_or<std::string>("witness_file", ""));
                       });
}

}  // namespace

RCAND_PLUGIN(RCAND_TEST_DRIVER_ID, "1.0.0", register_driver)
