// One-shot DNS-SD browse through avahi-daemon (rcanctl discover): every instance of a service type on the LAN,
// resolved to host, IPv4 address, port and TXT record. Blocks the caller up to `timeout`.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace rcand::mdns {

struct DiscoveredService {
  std::string name;     // the instance name ("sim-rover", "sim-rover #2")
  std::string host;     // "robot-a.local"
  std::string address;  // "10.210.0.1"
  std::uint16_t port = 0;
  std::map<std::string, std::string> txt;
};

struct BrowseOutcome {
  std::vector<DiscoveredService> services;  // sorted by name
  std::string error;                        // non-empty when browsing was impossible (no avahi-daemon)
};

// Returns when avahi-daemon says no more instances are expected soon and every one found is resolved, or at
// `timeout`, whichever comes first.
BrowseOutcome browse_services(const std::string& type, std::chrono::milliseconds timeout);

}  // namespace rcand::mdns
