// systemd integration without libsystemd: sd_notify datagrams, the watchdog feeder, journald priorities.
#include <doctest/doctest.h>

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include "libs/base/logging.hpp"
#include "libs/base/service_watchdog.hpp"
#include "libs/base/systemd_notify.hpp"
#include "notify_socket.hpp"
#include "temp_dir.hpp"

using rcand::test::NotifySocket;
using rcand::test::ScopedEnv;

TEST_CASE("notify_service_manager sends the state to $NOTIFY_SOCKET, and does nothing without it") {
  NotifySocket manager;
  {
    ScopedEnv socket("NOTIFY_SOCKET", manager.path());
    CHECK(rcand::notify_service_manager("READY=1\nSTATUS=serving"));
    CHECK(manager.next() == "READY=1\nSTATUS=serving");
  }
  ::unsetenv("NOTIFY_SOCKET");
  CHECK_FALSE(rcand::notify_service_manager("READY=1"));
  ScopedEnv relative("NOTIFY_SOCKET", "relative/path");
  CHECK_FALSE(rcand::notify_service_manager("READY=1"));
}

TEST_CASE("the watchdog interval comes from WATCHDOG_USEC, for this process only") {
  ::unsetenv("WATCHDOG_PID");
  {
    ScopedEnv usec("WATCHDOG_USEC", "5000000");
    CHECK(rcand::service_watchdog_interval() == std::chrono::microseconds(5'000'000));
    ScopedEnv other("WATCHDOG_PID", std::to_string(::getpid() + 1));
    CHECK_FALSE(rcand::service_watchdog_interval().has_value());
  }
  {
    ScopedEnv bad("WATCHDOG_USEC", "5s");
    CHECK_FALSE(rcand::service_watchdog_interval().has_value());
  }
  ::unsetenv("WATCHDOG_USEC");
  CHECK_FALSE(rcand::service_watchdog_interval().has_value());
}

TEST_CASE("the watchdog is fed only while the watched path answers") {
  NotifySocket manager;
  ScopedEnv socket("NOTIFY_SOCKET", manager.path());
  std::atomic<bool> alive{true};
  std::atomic<int> asked{0};
  std::atomic<long> within_ms{0};
  {
    rcand::ServiceWatchdog watchdog(std::chrono::milliseconds(40), [&](std::chrono::milliseconds within) {
      within_ms = static_cast<long>(within.count());
      ++asked;
      return alive.load();
    });
    CHECK(manager.next() == "WATCHDOG=1");
    CHECK(manager.next() == "WATCHDOG=1");
    alive = false;
    // Drain what was sent before the change; then nothing more comes while the path is hung.
    const int before = asked.load();
    while (asked.load() < before + 2) manager.next(100);
    while (!manager.next(0).empty()) {
    }
    const int hung_from = asked.load();
    CHECK(manager.next(150).empty());
    CHECK(asked.load() > hung_from);  // it kept asking
    alive = true;
    CHECK(manager.next() == "WATCHDOG=1");
  }
  CHECK(within_ms.load() == 10);  // a quarter of the interval
}

TEST_CASE("with stderr on the journal, log lines carry their priority and no timestamp") {
  rcand::test::TempDir dir;
  const auto file = dir.path() / "stderr";
  const int saved = ::dup(STDERR_FILENO);
  const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  REQUIRE(fd >= 0);
  ::dup2(fd, STDERR_FILENO);
  struct stat info {};
  ::fstat(STDERR_FILENO, &info);
  {
    ScopedEnv journal("JOURNAL_STREAM", std::to_string(info.st_dev) + ":" + std::to_string(info.st_ino));
    CHECK(rcand::stderr_is_journal());
    rcand::configure_logging("debug");
    auto log = rcand::logger("test.journal");
    log->error("an error");
    log->warn("a warning");
    log->info("some news");
    log->debug("a detail");
    log->flush();
  }
  ::dup2(saved, STDERR_FILENO);
  ::close(saved);
  ::close(fd);
  CHECK_FALSE(rcand::stderr_is_journal());  // JOURNAL_STREAM unset again
  rcand::configure_logging("info");         // back to the terminal pattern for the tests that follow
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  CHECK(text.str() ==
        "<3>error [test.journal] an error\n<4>warning [test.journal] a warning\n<6>info [test.journal] some news\n"
        "<7>debug [test.journal] a detail\n");
}
