#include "config_test_support.hpp"

#include <doctest/doctest.h>

#include <cstdlib>
#include <fstream>
#include <stdexcept>

namespace config_test {

using rcand::config::ConfigDiagnostic;
using rcand::config::ConfigError;

std::vector<std::string> minimal_lines() {
  return {
      "rcan_version: \"1.3\"",       // 1
      "metadata:",                   // 2
      "  robot_name: rover-1",       // 3
      "  robot_uuid: \"abcd1234\"",  // 4
      "  manufacturer: acme",        // 5
      "  model: rover",              // 6
  };
}

std::string join(const std::vector<std::string>& lines) {
  std::string out;
  for (const auto& line : lines) out += line + "\n";
  return out;
}

rcand::config::LoadedConfig parse_ok(const std::string& yaml) {
  try {
    return rcand::config::parse_robot_config(yaml, "test.rcan.yaml", "/srv/robot");
  } catch (const ConfigError& e) {
    FAIL("unexpected ConfigError:\n" << std::string(e.what()));
  }
  throw std::logic_error("unreachable");
}

std::vector<ConfigDiagnostic> parse_errors(const std::string& yaml) {
  try {
    rcand::config::parse_robot_config(yaml, "test.rcan.yaml", "/srv/robot");
  } catch (const ConfigError& e) {
    return e.diagnostics();
  }
  FAIL("expected a ConfigError for:\n" << yaml);
  return {};
}

std::vector<ConfigDiagnostic> errors_only(const std::vector<ConfigDiagnostic>& diagnostics) {
  std::vector<ConfigDiagnostic> out;
  for (const auto& d : diagnostics)
    if (d.severity == ConfigDiagnostic::Severity::Error) out.push_back(d);
  return out;
}

}  // namespace config_test
