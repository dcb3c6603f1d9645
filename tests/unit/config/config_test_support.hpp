// Shared helpers for the config tests: sample documents and "parse, expect failure, hand back the diagnostics".
#pragma once

#include "libs/config/robot_config.hpp"

#include <filesystem>
#include <string>
#include <vector>

#include "temp_dir.hpp"

namespace config_test {

// A SHA-256 in the form the config wants (this one is sha256("test-token")).
inline const std::string kHash = "4c5dc9b7708905f77f5e5d16316b5dfb425e68cb326dcd55a860e90a7707031e";

// The smallest valid file, one line per entry (line N of the file is lines[N-1]).
std::vector<std::string> minimal_lines();
std::string join(const std::vector<std::string>& lines);

// Parses `yaml` as "test.rcan.yaml" in /srv/robot and returns the result; FAILs the test when it throws.
rcand::config::LoadedConfig parse_ok(const std::string& yaml);
// Parses `yaml`, which must fail: returns every diagnostic of the ConfigError (FAILs the test when nothing is thrown).
std::vector<rcand::config::ConfigDiagnostic> parse_errors(const std::string& yaml);
// Only the errors among `diagnostics`.
std::vector<rcand::config::ConfigDiagnostic> errors_only(const std::vector<rcand::config::ConfigDiagnostic>& diagnostics);

using rcand::test::TempDir;

}  // namespace config_test
