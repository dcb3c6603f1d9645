// Without avahi-daemon (here: a system bus address nobody listens on) nothing blocks or crashes: the publisher
// starts and stops, the resolver fails at once (so the swarm takes the ip fallback), and the browser reports why.
#include <doctest/doctest.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdlib>
#include <sstream>

#include "libs/mdns/host_resolver.hpp"
#include "libs/mdns/service_browser.hpp"
#include "libs/mdns/service_publisher.hpp"

using namespace rcand;
using namespace std::chrono_literals;

namespace {

struct NoBus {
  NoBus() { ::setenv("DBUS_SYSTEM_BUS_ADDRESS", "unix:path=/nonexistent/rcand-test/system_bus_socket", 1); }
};

std::shared_ptr<spdlog::logger> capture(std::ostringstream& out) {
  auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(out);
  return std::make_shared<spdlog::logger>("test.mdns", sink);
}

}  // namespace

TEST_CASE("no avahi-daemon: the publisher logs once and stops promptly; the resolver and the browser fail at once") {
  NoBus no_bus;
  std::ostringstream log;
  {
    mdns::ServicePublisher publisher(capture(log));
    publisher.start({.name = "lonely", .port = 8000, .txt = [] { return std::map<std::string, std::string>{{"status", "idle"}}; }});
    publisher.refresh_soon();
    const auto stopping = std::chrono::steady_clock::now();
    publisher.stop();
    CHECK(std::chrono::steady_clock::now() - stopping < 1s);
  }
  const std::string text = log.str();
  CHECK(text.find("mDNS publisher: cannot reach the system D-Bus") != std::string::npos);
  CHECK(text.find("keeps serving HTTP") != std::string::npos);

  mdns::AvahiHostResolver resolver(capture(log));
  resolver.start();
  std::vector<std::string> addresses{"x"};
  std::string why;
  resolver.resolve("alex.local", [&](std::vector<std::string> found, std::string reason) {
    addresses = std::move(found);
    why = std::move(reason);
  });
  CHECK(addresses.empty());  // answered before resolve() returned: no waiting on a daemon that is not there
  CHECK(why == "mDNS unavailable (avahi-daemon not running)");
  resolver.stop();

  const auto browsed = mdns::browse_services("_rcan._tcp", 2s);
  CHECK(browsed.services.empty());
  CHECK(browsed.error.find("cannot reach avahi-daemon") == 0);
}
