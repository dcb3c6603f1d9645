#include "latency_timer.hpp"

#include <filesystem>
#include <fstream>

namespace rcand::plugins::dynamixel {

std::optional<LatencyTimer> read_latency_timer(const std::string& port, const std::string& sysfs_root) {
  std::error_code ec;
  std::filesystem::path device = std::filesystem::canonical(port, ec);  // by-id links resolve to ttyUSBn
  if (ec) device = port;
  const std::string path = sysfs_root + "/bus/usb-serial/devices/" + device.filename().string() + "/latency_timer";
  std::ifstream in(path);
  int ms = -1;
  if (!(in >> ms) || ms < 0) return std::nullopt;
  return LatencyTimer{path, ms};
}

std::string latency_timer_warning(const LatencyTimer& timer) {
  if (timer.milliseconds < kDefaultLatencyTimerMs) return {};
  return "the USB serial adapter's latency timer is " + std::to_string(timer.milliseconds) +
         " ms: every servo reply waits that long, so sync reads cannot keep 100 Hz. Set it to 1: echo 1 | sudo tee " +
         timer.sysfs_path + " (or a udev rule: ATTR{latency_timer}=\"1\")";
}

}  // namespace rcand::plugins::dynamixel
