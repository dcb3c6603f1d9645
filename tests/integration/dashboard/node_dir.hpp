// The browser tests' Node.js side: tests/dashboard's scripts beside playwright-core (pinned in
// tests/dashboard/package-lock.json, installed by `npm ci` once per lock file) in <build>/tests/dashboard-node, where
// Node resolves their imports. Chromium, Node.js and npm come from packaging/install-deps.sh.
#pragma once

#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "rcand_process.hpp"

namespace rcand::test {

inline std::string slurp_file(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

inline std::filesystem::path prepared_node_dir() {
  namespace fs = std::filesystem;
  const fs::path source = fs::path(RCAND_SOURCE_DIR) / "tests/dashboard";
  const fs::path dir = fs::path(RCAND_BINARY_DIR) / "tests/dashboard-node";
  fs::create_directories(dir);
  for (const char* name : {"package.json", "drive.mjs", "state.mjs", "origin_probe.mjs"})
    fs::copy_file(source / name, dir / name, fs::copy_options::overwrite_existing);
  const std::string lock = slurp_file(source / "package-lock.json");
  if (!fs::exists(dir / "node_modules/playwright-core") || slurp_file(dir / "package-lock.json") != lock) {
    fs::copy_file(source / "package-lock.json", dir / "package-lock.json", fs::copy_options::overwrite_existing);
    const auto npm = run_tool("/bin/sh", {"-c", "cd \"$0\" && npm ci --no-audit --no-fund --ignore-scripts", dir.string()});
    INFO(npm.out, npm.err);
    REQUIRE_MESSAGE(npm.exit_code == 0, "npm ci of playwright-core failed (packaging/install-deps.sh installs npm)");
  }
  return dir;
}

}  // namespace rcand::test
