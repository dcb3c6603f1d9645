// Which swarm hosts go to mDNS.
#include <doctest/doctest.h>

#include "libs/mdns/host_resolver.hpp"

using rcand::mdns::is_mdns_host;

TEST_CASE("*.local names (any case, trailing dot) are mDNS hosts; addresses and other names are not") {
  CHECK(is_mdns_host("alex.local"));
  CHECK(is_mdns_host("Alex.LOCAL"));
  CHECK(is_mdns_host("alex.local."));
  CHECK(is_mdns_host("rover-1.lab.local"));
  CHECK_FALSE(is_mdns_host(".local"));
  CHECK_FALSE(is_mdns_host("local"));
  CHECK_FALSE(is_mdns_host("alex.localdomain"));
  CHECK_FALSE(is_mdns_host("alex.example.com"));
  CHECK_FALSE(is_mdns_host("192.168.68.91"));
  CHECK_FALSE(is_mdns_host(""));
}
