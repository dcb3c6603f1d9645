// A config another user could change is refused (issue 28 item 5; libs/base/file_trust.hpp), as sshd's StrictModes
// refuses such a ~/.ssh: the file, each conf.d fragment, conf.d itself and the file's directory, each named with the
// chmod or chown that fixes it. Group-writable is fine for a group only trusted users are in (the 0664 of a umask
// 002 with user private groups), a sticky directory is fine above the file (not as conf.d).
#include <doctest/doctest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "config_test_support.hpp"
#include "libs/base/file_trust.hpp"

using namespace config_test;
using rcand::untrusted_writers;
using rcand::config::ConfigError;
using rcand::config::load_robot_config;
namespace fs = std::filesystem;

namespace {

// The refusal's text when loading `file` must fail (empty, and a failed check, when it loads).
std::string trust_refusal(const fs::path& file) {
  try {
    load_robot_config(file);
  } catch (const ConfigError& e) {
    return e.what();
  }
  FAIL_CHECK("expected " << file << " to be refused");
  return {};
}

struct stat stat_with(uid_t uid, gid_t gid, mode_t mode) {
  struct stat info {};
  info.st_uid = uid;
  info.st_gid = gid;
  info.st_mode = mode;
  return info;
}

}  // namespace

TEST_CASE("file trust: owner root or the user, no write for untrusted group members or others") {
  const uid_t me = ::geteuid();
  const gid_t nobody_group = 65534;  // nogroup: nobody's, never only trusted users'
  CHECK(untrusted_writers("/f", stat_with(0, 0, S_IFREG | 0644), me).empty());
  CHECK(untrusted_writers("/f", stat_with(me, 0, S_IFREG | 0600), me).empty());
  const auto foreign = untrusted_writers("/f", stat_with(12345, 0, S_IFREG | 0644), 4242);
  CHECK(foreign.find("owned by uid 12345, not by root or uid 4242") != std::string::npos);
  CHECK(foreign.find("chown root '/f'") != std::string::npos);
  const auto world = untrusted_writers("/f", stat_with(0, 0, S_IFREG | 0646), me);
  CHECK(world.find("writable by every user (mode 0646)") != std::string::npos);
  CHECK(world.find("chmod o-w '/f'") != std::string::npos);
  const auto group = untrusted_writers("/f", stat_with(0, nobody_group, S_IFREG | 0666), me);
  CHECK(group.find("writable by group") != std::string::npos);
  CHECK(group.find("chmod go-w '/f'") != std::string::npos);
  // A sticky directory: others may add files, not replace ours - fine where the caller allows it, never for conf.d.
  CHECK(untrusted_writers("/d", stat_with(0, 0, S_IFDIR | 01777), me, true).empty());
  CHECK_FALSE(untrusted_writers("/d", stat_with(0, 0, S_IFDIR | 01777), me).empty());
  CHECK_FALSE(untrusted_writers("/d", stat_with(0, 0, S_IFDIR | 0777), me, true).empty());
  // A group whose members are all trusted: the user's own private group, root's group.
  if (rcand::group_only_trusted(::getegid(), me))
    CHECK(untrusted_writers("/f", stat_with(me, ::getegid(), S_IFREG | 0664), me).empty());
}

TEST_CASE("config trust: a config file, fragment or directory another user could change is refused, named, fixable") {
  TempDir dir("rcand-trust");
  const auto file = dir.write("robot.rcan.yaml", join(minimal_lines()));
  const auto fragment = dir.write("conf.d/50-site.yaml", "runtime:\n  logging:\n    level: warn\n");
  REQUIRE(load_robot_config(file).config.runtime.log_level == "warn");

  SUBCASE("a fragment every user may write") {
    fs::permissions(fragment, fs::perms::others_write, fs::perm_options::add);
    const auto refusal = trust_refusal(fragment.parent_path().parent_path() / "robot.rcan.yaml");
    CHECK(refusal.find(fragment.string()) != std::string::npos);
    CHECK(refusal.find("refused") != std::string::npos);
    CHECK(refusal.find("chmod o-w '" + fragment.string() + "'") != std::string::npos);
  }
  SUBCASE("the main file every user may write") {
    fs::permissions(file, fs::perms::others_write, fs::perm_options::add);
    CHECK(trust_refusal(file).find("chmod o-w '" + file.string() + "'") != std::string::npos);
  }
  SUBCASE("conf.d every user may write (anyone could add a fragment), sticky or not") {
    fs::permissions(fragment.parent_path(), fs::perms::others_all | fs::perms::sticky_bit, fs::perm_options::add);
    CHECK(trust_refusal(file).find("conf.d directory") != std::string::npos);
  }
  SUBCASE("the file's directory every user may write; sticky (like /tmp) it is fine") {
    fs::permissions(dir.path(), fs::perms::others_all, fs::perm_options::add);
    CHECK(trust_refusal(file).find("the config file's directory") != std::string::npos);
    fs::permissions(dir.path(), fs::perms::sticky_bit, fs::perm_options::add);
    CHECK_NOTHROW(load_robot_config(file));
  }
  if (::geteuid() != 0) {
    MESSAGE("SKIPPED: the owner and group rules need root to chown a file to another user");
    return;
  }
  SUBCASE("a fragment owned by another user (as root: chown'd to nobody)") {
    REQUIRE(::chown(fragment.c_str(), 65534, 65534) == 0);
    const auto refusal = trust_refusal(file);
    CHECK(refusal.find("owned by") != std::string::npos);
    CHECK(refusal.find("chown root '" + fragment.string() + "'") != std::string::npos);
  }
  SUBCASE("a fragment writable by a group with other members") {
    REQUIRE(::chown(fragment.c_str(), 0, 65534) == 0);
    fs::permissions(fragment, fs::perms::group_write, fs::perm_options::add);
    CHECK(trust_refusal(file).find("chmod g-w '" + fragment.string() + "'") != std::string::npos);
  }
  SUBCASE("--check-config --as-user: judged for that user, whose files it trusts") {
    REQUIRE(::chown(fragment.c_str(), 65534, 0) == 0);
    rcand::config::LoadOptions as_nobody;
    as_nobody.user = 65534;
    CHECK_THROWS_AS(load_robot_config(file), ConfigError);
    CHECK(load_robot_config(file, as_nobody).config.runtime.log_level == "warn");
  }
}
