// A pseudo-terminal pair standing in for a USB serial adapter: the driver opens slave_path() like /dev/ttyUSB0, the
// servo emulator reads and writes master(). The pair keeps a slave descriptor of its own open (raw from the start),
// so the master never sees a hang-up while the driver's process comes and goes (kill -9 in the watchdog test).
#pragma once

#include <string>

namespace rcand::plugins::dynamixel::testing {

class PtyPair {
 public:
  PtyPair();  // throws std::runtime_error
  ~PtyPair();
  PtyPair(const PtyPair&) = delete;
  PtyPair& operator=(const PtyPair&) = delete;

  int master() const noexcept { return master_; }
  const std::string& slave_path() const noexcept { return slave_path_; }

 private:
  int master_ = -1;
  int slave_ = -1;
  std::string slave_path_;
};

}  // namespace rcand::plugins::dynamixel::testing
