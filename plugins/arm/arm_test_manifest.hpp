// The arm plugin's manifest from the source tree, for the tests that load the plugin on the fake host.
#pragma once

#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include <fstream>

inline nlohmann::json arm_manifest() {
  std::ifstream in(RCAND_SOURCE_DIR "/manifests/arm.json");
  REQUIRE(in.good());
  return nlohmann::json::parse(in);
}
