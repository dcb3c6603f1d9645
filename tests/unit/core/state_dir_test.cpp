// runtime.state_dir: the running marker tells a clean shutdown from a crash, the latch record survives a restart (a
// full disk included), one rcand per state dir (a refused one writes nothing and is told who holds it), and an
// unusable one is an error naming the key.
#include <doctest/doctest.h>

#include <stdlib.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "kernel/safety/state_dir.hpp"
#include "small_filesystem.hpp"

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

std::string state_text(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace

TEST_CASE("a fresh state dir: created and locked, nothing from before; marked running, the slot reserved") {
  StateScratch scratch;
  const auto dir = scratch.dir / "a" / "b";
  StateDir state(dir);
  CHECK_FALSE(state.previous().unclean_exit);
  CHECK_FALSE(state.previous().latch.has_value());
  CHECK_FALSE(std::filesystem::exists(dir / "running"));  // locking alone writes no state
  state.mark_running();
  CHECK(std::filesystem::exists(dir / "running"));
  CHECK(std::filesystem::file_size(dir / "estop.slot") == StateDir::kSlotBytes);
  state.clean_exit({});
  CHECK_FALSE(std::filesystem::exists(dir / "running"));
}

TEST_CASE("without a clean exit the next open sees the marker: the last run ended uncleanly") {
  StateScratch scratch;
  {
    StateDir crashed(scratch.dir);
    crashed.mark_running();
  }  // destroyed without clean_exit: as a kill -9 leaves it
  StateDir state(scratch.dir);
  CHECK(state.previous().unclean_exit);
  CHECK(state.previous().marker.find("pid ") == 0);
}

TEST_CASE("a clean exit keeps the latch as it was") {
  StateScratch scratch;
  {
    StateDir state(scratch.dir);
    state.mark_running();
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
    state.mark_running();
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
    state.mark_running();
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

TEST_CASE("an unreadable latch record counts as latched; so does an empty one, but not a slot never written") {
  StateScratch scratch;
  for (const char* text : {"{\"latch", ""}) {
    std::ofstream(scratch.dir / "estop.json") << text;
    std::ofstream(scratch.dir / "estop.slot") << std::string(StateDir::kSlotBytes, ' ');
    StateDir state(scratch.dir);
    REQUIRE(state.previous().latch.has_value());
    CHECK(state.previous().latch->latched);
    CHECK(state.previous().latch->reason.find("unreadable") != std::string::npos);
  }
}

TEST_CASE("one rcand per state dir, told who holds it; an unusable one is an error naming runtime.state_dir") {
  StateScratch scratch;
  StateDir first(scratch.dir);
  CHECK_THROWS_WITH_AS(StateDir{scratch.dir}, doctest::Contains("runtime.state_dir"), std::runtime_error);
  CHECK_THROWS_WITH_AS(StateDir{scratch.dir}, doctest::Contains("in use by another rcand"), std::runtime_error);
  // The holder is named from the lock file, though it has not marked the dir running yet.
  const std::string holder = "pid " + std::to_string(::getpid()) + ",";
  CHECK_THROWS_WITH_AS(StateDir{scratch.dir}, doctest::Contains(holder.c_str()), std::runtime_error);
  CHECK_FALSE(std::filesystem::exists(scratch.dir / "running"));
  const auto file = scratch.dir / "plain-file";
  std::ofstream(file) << "x";
  CHECK_THROWS_WITH_AS(StateDir{file}, doctest::Contains("runtime.state_dir"), std::runtime_error);
  CHECK_THROWS_WITH_AS(StateDir{file / "below"}, doctest::Contains("runtime.state_dir"), std::runtime_error);
}

TEST_CASE("the newer of estop.json and estop.slot wins; a slot cut by a crash falls back to estop.json") {
  StateScratch scratch;
  {
    StateDir state(scratch.dir);
    state.mark_running();
    state.clean_exit({true, "first stop", "alice", 1});
  }
  // As if estop.json could not be replaced the last time (a full disk): the slot alone has the newer record.
  const std::string older = state_text(scratch.dir / "estop.json");
  {
    StateDir state(scratch.dir);
    state.mark_running();
    state.clean_exit({true, "second stop", "bob", 2});
  }
  std::ofstream(scratch.dir / "estop.json") << older;
  {
    StateDir state(scratch.dir);
    REQUIRE(state.previous().latch.has_value());
    CHECK(state.previous().latch->reason == "second stop");
    state.mark_running();
    state.clean_exit({true, "third stop", "carol", 3});
  }
  // A slot whose rewrite was cut short does not parse: estop.json, written after the slot before it, is read.
  std::string slot = state_text(scratch.dir / "estop.slot");
  slot.replace(10, 20, std::string(20, '\0'));
  std::ofstream(scratch.dir / "estop.slot", std::ios::binary) << slot;
  StateDir state(scratch.dir);
  REQUIRE(state.previous().latch.has_value());
  CHECK(state.previous().latch->latched);
  CHECK(state.previous().latch->reason == "third stop");
}

TEST_CASE("a disk that fills up while rcand runs: the latch and its reason survive a crash and a clean stop") {
  StateScratch scratch;
  rcand::test::SmallFilesystem disk(scratch.dir / "small", 64 * 1024);
  if (!disk.mounted()) {
    REQUIRE_MESSAGE(!disk.root(), disk.why_not());  // as root (CI) a small filesystem must be made: never skipped
    MESSAGE("SKIPPED: " << disk.why_not());
    return;
  }
  const auto dir = disk.path() / "state";
  {
    const StateDir::LatchRecord now{true, "bumper hit while the disk was full", "plugin", 42};
    StateDir state(dir);
    state.mark_running();
    state.start_writer([&now] { return now; });
    REQUIRE(disk.fill());
    state.latch_changed();
  }               // a crash right after the latch (the pending change is written as the writer stops)
  disk.unfill();  // the operator makes room, then starts rcand again
  {
    StateDir state(dir);
    CHECK(state.previous().unclean_exit);
    REQUIRE(state.previous().latch.has_value());
    CHECK(state.previous().latch->latched);
    CHECK(state.previous().latch->reason == "bumper hit while the disk was full");
    state.mark_running();
    REQUIRE(disk.fill());
    state.clean_exit({true, "operator stop on a full disk", "alice", 7});
  }
  disk.unfill();
  StateDir state(dir);
  CHECK_FALSE(state.previous().unclean_exit);  // the record was kept, so the clean stop removed the marker
  REQUIRE(state.previous().latch.has_value());
  CHECK(state.previous().latch->reason == "operator stop on a full disk");
  CHECK(state.previous().latch->source == "alice");
}
