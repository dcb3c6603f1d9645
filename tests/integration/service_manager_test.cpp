// rcand under systemd's Type=notify (issue 19): READY once it serves, RELOADING/READY around a SIGHUP reload,
// the watchdog fed while the e-stop's thread answers, STOPPING on SIGTERM. The service manager is this test.
#include <doctest/doctest.h>

#include <csignal>

#include "notify_socket.hpp"
#include "rcand_process.hpp"

using namespace rcand::test;

TEST_CASE("rcand tells the service manager it is ready, reloading and stopping, and feeds its watchdog") {
  NotifySocket manager;
  std::optional<RcandProcess> rcand;
  {
    ScopedEnv socket("NOTIFY_SOCKET", manager.path());
    ScopedEnv watchdog("WATCHDOG_USEC", "200000");  // 200 ms: a keep-alive every 100 ms
    rcand.emplace(sim_config());                    // inherits the environment
  }
  CHECK(manager.next_state() == "READY=1\nSTATUS=serving on port " + std::to_string(rcand->port()));
  for (int i = 0; i < 3; ++i) CHECK(manager.next() == "WATCHDOG=1");

  REQUIRE(::kill(rcand->pid(), SIGHUP) == 0);
  CHECK(manager.next_state() == "RELOADING=1");
  CHECK(manager.next_state() == "READY=1");
  CHECK(manager.next() == "WATCHDOG=1");  // still fed after the reload

  REQUIRE(::kill(rcand->pid(), SIGTERM) == 0);
  CHECK(manager.next_state() == "STOPPING=1");
}
