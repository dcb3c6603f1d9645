// libFuzzer target: a robot's .rcan.yaml from bytes, through the same loader as a file (parse_robot_config).
// Only ConfigError may escape (anything else is a crash), and it carries at least one error, each with the file's
// name and a position that is inside the text or 0 (the whole file).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fuzz_check.hpp"
#include "libs/config/robot_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view yaml(reinterpret_cast<const char*>(data), size);
  const int lines = static_cast<int>(std::count(yaml.begin(), yaml.end(), '\n')) + 1;
  try {
    const auto loaded = rcand::config::parse_robot_config(yaml, "fuzz.rcan.yaml", "/nonexistent-fuzz-dir");
    for (const auto& warning : loaded.warnings)
      RCAND_FUZZ_CHECK(warning.severity == rcand::config::ConfigDiagnostic::Severity::Warning, "a warning is a warning");
    RCAND_FUZZ_CHECK(!loaded.config.robot_name.empty(), "an accepted config names the robot");
  } catch (const rcand::config::ConfigError& error) {
    const auto& diagnostics = error.diagnostics();
    RCAND_FUZZ_CHECK(std::any_of(diagnostics.begin(), diagnostics.end(),
                                 [](const auto& d) { return d.severity == rcand::config::ConfigDiagnostic::Severity::Error; }),
                     "a ConfigError carries an error");
    for (const auto& diagnostic : diagnostics) {
      RCAND_FUZZ_CHECK(diagnostic.format().rfind("fuzz.rcan.yaml", 0) == 0, "a diagnostic starts with the file name");
      RCAND_FUZZ_CHECK(diagnostic.mark.line >= 0 && diagnostic.mark.line <= lines, "a diagnostic's line is in the file");
      RCAND_FUZZ_CHECK(diagnostic.mark.column >= 0, "a diagnostic's column is not negative");
    }
  }
  return 0;
}
