// A pluggable name resolver: the swarm's fan-out asks it for the hosts it handles (mDNS "*.local" names, resolved
// through avahi-daemon by libs/mdns) instead of getaddrinfo. It must never block the caller: the fan-out runs every
// peer of a broadcast on one event loop, and a stop has 300 ms per peer. In libs/base so that the resolver's
// implementation (libs/mdns) and its user (libs/swarm) need not know each other.
#pragma once

#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace rcand {

class HostResolver {
 public:
  // addresses: IP literals ("10.0.0.2"), empty on failure; why: the reason when empty.
  using Done = std::function<void(std::vector<std::string> addresses, std::string why)>;

  virtual ~HostResolver() = default;
  // Whether `host` is this resolver's to resolve.
  virtual bool handles(std::string_view host) const = 0;
  // Calls `done` exactly once, on any thread (possibly before returning, from a cache). Never blocks.
  virtual void resolve(const std::string& host, Done done) = 0;
};

}  // namespace rcand
