#include "kernel/plugins/descriptor_check.hpp"

#include <doctest/doctest.h>

#include <cstddef>

using rcand::kernel::check_descriptor;
using rcand::PluginManifest;
using rcand::kernel::PluginState;

namespace {

void no_op_register(rcand_registrar*) {}

PluginManifest manifest() {
  PluginManifest m;
  m.file = "/plugins/x.json";
  m.id = "org.rcand.x";
  m.version = "1.0.0";
  m.abi_major = 1;
  return m;
}

rcand_plugin_descriptor good_descriptor() {
  return {sizeof(rcand_plugin_descriptor), RCAND_DESCRIPTOR_MAGIC, RCAND_ABI_MAJOR, RCAND_ABI_MINOR, "org.rcand.x", "1.0.0",
          "test", no_op_register};
}

}  // namespace

TEST_CASE("check_descriptor accepts a descriptor that matches the kernel and the manifest") {
  const auto d = good_descriptor();
  CHECK_FALSE(check_descriptor(&d, manifest()).has_value());
}

TEST_CASE("check_descriptor rejects layouts and ABIs the kernel cannot use") {
  auto d = good_descriptor();
  PluginState expected = PluginState::IncompatibleAbi;
  std::string reason;
  SUBCASE("null") {
    const auto verdict = check_descriptor(nullptr, manifest());
    REQUIRE(verdict);
    CHECK(verdict->state == expected);
    CHECK(verdict->reason == "the entry point returned no descriptor");
    return;
  }
  SUBCASE("bad magic") {
    d.magic = 0x12345678u;
    reason = "descriptor magic 0x12345678 is not 0x52434e44";
  }
  SUBCASE("smaller than the 1.0 layout") {
    d.struct_size = offsetof(rcand_plugin_descriptor, register_plugin);
    reason = "smaller than the ABI 1.0 layout";
  }
  SUBCASE("larger than the kernel's") {
    d.struct_size = sizeof(rcand_plugin_descriptor) + 8;
    reason = "larger than the kernel's";
  }
  SUBCASE("another major") {
    d.abi_major = RCAND_ABI_MAJOR + 1;
    reason = "built for ABI " + std::to_string(RCAND_ABI_MAJOR + 1) + ", kernel speaks " + std::to_string(RCAND_ABI_MAJOR);
  }
  SUBCASE("newer minor") {
    d.abi_minor = RCAND_ABI_MINOR + 1;
    reason = "minor newer than the kernel's";
  }
  SUBCASE("no register function") {
    d.register_plugin = nullptr;
    reason = "no register function";
  }
  SUBCASE("id differs") {
    d.plugin_id = "org.rcand.y";
    expected = PluginState::ManifestMismatch;
    reason = "descriptor id 'org.rcand.y' differs from manifest id 'org.rcand.x'";
  }
  SUBCASE("id null") {
    d.plugin_id = nullptr;
    expected = PluginState::ManifestMismatch;
    reason = "descriptor id '(null)'";
  }
  SUBCASE("version differs") {
    d.version = "1.0.1";
    expected = PluginState::ManifestMismatch;
    reason = "descriptor version '1.0.1' differs from manifest version '1.0.0'";
  }
  const auto verdict = check_descriptor(&d, manifest());
  REQUIRE(verdict.has_value());
  CHECK(verdict->state == expected);
  CHECK(verdict->reason.find(reason) != std::string::npos);
  CHECK_FALSE(verdict->hint.empty());
}
