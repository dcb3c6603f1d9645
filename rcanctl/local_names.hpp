// "*.local" robot names for rcanctl, resolved through avahi-daemon directly: a laptop or board without libnss-mdns
// (Debian's default) can still reach "alex.local". Other names go to getaddrinfo as before.
#pragma once

#include <chrono>
#include <memory>
#include <string>

#include "libs/base/host_resolver.hpp"

namespace rcand::rcanctl {

// The resolver the swarm fan-out takes for "*.local" hosts (started; stops when the last user lets go).
std::shared_ptr<HostResolver> local_name_resolver();

// `host` itself when it is not an mDNS name, else its first address. Throws std::runtime_error saying why not
// ("alex.local: no mDNS answer in time", "alex.local: mDNS unavailable ...").
std::string address_of(const std::string& host, std::chrono::milliseconds timeout);

}  // namespace rcand::rcanctl
