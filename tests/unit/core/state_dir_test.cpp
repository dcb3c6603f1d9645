// runtime.state_dir: the running marker tells a clean shutdown from a crash, the latch record survives a restart,
// one rcand per state dir, and an unusable one is an error naming the key.
#include <doctest/doctest.h>

#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "kernel/safety/state_dir.hpp"

using rcand::kernel::StateDir;

namespace {

struct StateScratch {
  std::filesystem::path dir;
  StateScratch() {
    std::string pattern = (std::filesystem::temp_directory_path() / "rcand-state-unit-XXXXXX").string();
    REQUIRE(::mkdtemp(pattern.data()) != nullptr);
    dir = pattern;
  }
  ~StateScratch() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
};

}  // namespace

TEST_CASE("a fresh state dir: created, nothing from before, the running marker written") {
  StateScratch scratch;
  const auto dir = scratch.dir / "a" / "b";
  StateDir state(dir);
  CHECK_FALSE(state.previous().unclean_exit);
  CHECK_FALSE(state.previous().latch.has_value());
  CHECK(std::filesystem::exists(dir / "running"));
  state.clean_exit({});
  CHECK_FALSE(std::filesystem::exists(dir / "running"));
}

TEST_CASE("without a clean exit the next open sees the marker: the last run ended uncleanly") {
  StateScratch scratch;
  { StateDir crashed(scratch.dir); }  // destroyed without clean_exit: as a kill -9 leaves it
  StateDir state(scratch.dir);
  CHECK(state.previous().unclean_exit);
  CHECK(state.previous().marker.find("pid ") == 0);
}

TEST_CASE("a clean exit keeps the latch as it was") {
  StateScratch scratch;
  {
    StateDir state(scratch.dir);
    state.clean_exit({true, "operator pressed stop", "alice", 1234});
  }
  {
    StateDir state(scratch.dir);
    CHECK_FALSE(state.previous().unclean_exit);
    REQUIRE(state.previous().latch.has_value());
    CHECK(state.previous().latch->latched);
    CHECK(state.previous().latch->reason == "operator pressed stop");
    CHECK(state.previous().latch->source == "alice");
    CHECK(state.previous().latch->since_ms == 1234);
    state.clean_exit({false, "", "", 0});
  }
  StateDir state(scratch.dir);
  REQUIRE(state.previous().latch.has_value());
  CHECK_FALSE(state.previous().latch->latched);
}

TEST_CASE("the writer records each change off the caller's thread; a pending one is written before it stops") {
  StateScratch scratch;
  {
    const StateDir::LatchRecord now{true, "bumper", "plugin", 42};  // outlives the writer, which reads it
    StateDir state(scratch.dir);
    state.start_writer([&now] { return now; });
    state.latch_changed();
  }  // no clean exit: a crash right after the latch
  StateDir state(scratch.dir);
  CHECK(state.previous().unclean_exit);
  REQUIRE(state.previous().latch.has_value());
  CHECK(state.previous().latch->latched);
  CHECK(state.previous().latch->reason == "bumper");
  CHECK_FALSE(std::filesystem::exists(scratch.dir / "estop.json.tmp"));  // replaced atomically
}

TEST_CASE("an unreadable latch record counts as latched") {
  StateScratch scratch;
  std::ofstream(scratch.dir / "estop.json") << "{\"latch";
  StateDir state(scratch.dir);
  REQUIRE(state.previous().latch.has_value());
  CHECK(state.previous().latch->latched);
  CHECK(state.previous().latch->reason.find("unreadable") != std::string::npos);
}

TEST_CASE("one rcand per state dir; an unusable one is an error naming runtime.state_dir") {
  StateScratch scratch;
  StateDir first(scratch.dir);
  CHECK_THROWS_WITH_AS(StateDir{scratch.dir}, doctest::Contains("runtime.state_dir"), std::runtime_error);
  CHECK_THROWS_WITH_AS(StateDir{scratch.dir}, doctest::Contains("in use by another rcand"), std::runtime_error);
  const auto file = scratch.dir / "plain-file";
  std::ofstream(file) << "x";
  CHECK_THROWS_WITH_AS(StateDir{file}, doctest::Contains("runtime.state_dir"), std::runtime_error);
  CHECK_THROWS_WITH_AS(StateDir{file / "below"}, doctest::Contains("runtime.state_dir"), std::runtime_error);
}
