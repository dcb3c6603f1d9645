#include "arduino_pty.hpp"

#include <fcntl.h>
#include <stdlib.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace rcand::plugins::arduino::testing {

ArduinoPty::ArduinoPty() {
  master_ = ::posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC);
  if (master_ < 0) throw std::runtime_error(std::string("posix_openpt: ") + std::strerror(errno));
  char name[128] = {};
  if (::grantpt(master_) != 0 || ::unlockpt(master_) != 0 || ::ptsname_r(master_, name, sizeof name) != 0) {
    ::close(master_);
    throw std::runtime_error(std::string("pseudo-terminal setup: ") + std::strerror(errno));
  }
  slave_path_ = name;
  const int slave = ::open(name, O_RDWR | O_NOCTTY | O_CLOEXEC);
  termios tio{};
  if (slave < 0 || ::tcgetattr(slave, &tio) != 0) {
    if (slave >= 0) ::close(slave);
    ::close(master_);
    throw std::runtime_error("cannot open " + slave_path_ + ": " + std::strerror(errno));
  }
  ::cfmakeraw(&tio);  // no echo of the driver's lines back to it before it sets the port up itself
  ::tcsetattr(slave, TCSANOW, &tio);
  ::close(slave);  // the master now reads as hung up until the driver opens the port
  ::fcntl(master_, F_SETFL, ::fcntl(master_, F_GETFL) | O_NONBLOCK);
}

ArduinoPty::~ArduinoPty() {
  if (master_ >= 0) ::close(master_);
}

}  // namespace rcand::plugins::arduino::testing
