// The harness's half of the sanitizer build: a report an rcand child writes to its stderr (ASan, LSan at exit, UBSan)
// fails the test that started it, even when the test never looks at the child's exit status.
#include <doctest/doctest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>

#include "rcand_process.hpp"

namespace {

using rcand::test::RcandProcess;

// Runs, in a forked child, a harness-managed "rcand" that is really a shell script: it announces itself as rcand
// does, after writing `report` to stderr, and exits 0 on SIGTERM. Returns the child's wait status.
int run_fake_rcand(const std::string& report) {
  // The child aborts before its RcandProcess can remove its directory: it makes it in one the parent removes.
  const rcand::test::TempDir scratch("rcand-sanitizer-report");
  // Whatever doctest has buffered would otherwise be written again by the child (a CI log showed it four times).
  std::cout.flush();
  std::fflush(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    if (!std::freopen("/dev/null", "w", stderr)) _exit(3);  // the expected report would only confuse a CI log
    if (::setenv("TMPDIR", scratch.path().c_str(), 1) != 0) _exit(3);
    ::signal(SIGABRT, SIG_DFL);  // the harness's abort ends this child plainly, without doctest's crash report
    {
      // The report is written before the "listening" line, so it is on stderr before the harness can stop us.
      const std::string script = "trap 'exit 0' TERM; printf '%s\\n' '" + report +
                                 "' >&2; echo 'rcand: listening on http://127.0.0.1:1'; echo 'rcand: capabilities started'; "
                                 "while :; do sleep 0.05; done";
      RcandProcess fake(rcand::test::sim_config(), {"/bin/sh", "-c", script, "fake-rcand"}, "127.0.0.1");
    }
    _exit(0);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  return status;
}

}  // namespace

TEST_CASE("a sanitizer report in an rcand child fails the test that started it") {
  for (const std::string report :
       {"==42==ERROR: AddressSanitizer: heap-use-after-free on address 0x602",
        "==42==ERROR: LeakSanitizer: detected memory leaks", "src/x.cpp:3:5: runtime error: signed integer overflow"}) {
    CAPTURE(report);
    const int status = run_fake_rcand(report);
    CHECK(WIFSIGNALED(status));
    CHECK(WTERMSIG(status) == SIGABRT);
  }
}

TEST_CASE("an rcand child with a clean stderr does not fail the test") {
  const int status = run_fake_rcand("rcand: shutting down");
  REQUIRE(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 0);
}
