// Whether a configured listen address is a loopback one (open auth mode and the R2R UDP bind default depend on it).
#pragma once

#include <string>

namespace rcand {

// True for a literal loopback address (127.0.0.0/8, ::1); false for anything else, names and garbage included.
bool is_loopback_address(const std::string& address);

}  // namespace rcand
