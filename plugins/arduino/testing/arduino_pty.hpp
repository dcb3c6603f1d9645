// A pseudo-terminal standing in for the Arduino's USB serial port: the driver opens slave_path() like /dev/ttyACM0,
// the emulator reads and writes master(). The slave is set raw and closed again at once, so the master sees a
// hang-up whenever no one has the port open, and the emulator can reset the board when the driver opens it (an Uno
// resets when DTR rises) and keep its watchdog running when rcand is killed.
#pragma once

#include <string>

namespace rcand::plugins::arduino::testing {

class ArduinoPty {
 public:
  ArduinoPty();  // throws std::runtime_error
  ~ArduinoPty();
  ArduinoPty(const ArduinoPty&) = delete;
  ArduinoPty& operator=(const ArduinoPty&) = delete;

  int master() const noexcept { return master_; }
  const std::string& slave_path() const noexcept { return slave_path_; }

 private:
  int master_ = -1;
  std::string slave_path_;
};

}  // namespace rcand::plugins::arduino::testing
