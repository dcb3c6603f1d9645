// The FTDI-style USB serial adapters (the U2D2 among them) hold received bytes for up to their latency timer before
// passing them to the host: 16 ms by default, which turns every 1 Mbps status reply into a 16 ms wait and makes a
// 100 Hz loop impossible. The kernel shows it in /sys/bus/usb-serial/devices/<tty>/latency_timer.
#pragma once

#include <optional>
#include <string>

namespace rcand::plugins::dynamixel {

inline constexpr int kDefaultLatencyTimerMs = 16;

struct LatencyTimer {
  std::string sysfs_path;  // the file read
  int milliseconds;
};

// The latency timer of the adapter behind `port` (/dev/ttyUSB0, or a /dev/serial/by-id/... link to it); nullopt when
// the port is not a usb-serial device (a native UART, a pseudo-terminal) or the file cannot be read.
std::optional<LatencyTimer> read_latency_timer(const std::string& port, const std::string& sysfs_root = "/sys");

// The warning for a 16 ms timer, with the fix; empty when the timer is fine.
std::string latency_timer_warning(const LatencyTimer& timer);

}  // namespace rcand::plugins::dynamixel
