// rcanctl doctor: what is wrong with this robot's setup, each with the command that fixes it: the config (rcand
// --check-config, as the service's user), the robot answering and its state, the plugins, the e-stop, avahi-daemon,
// the clock and the port.
#pragma once

#include <span>
#include <string>

namespace rcand::rcanctl {

int run_doctor(std::span<const std::string> args);

}  // namespace rcand::rcanctl
