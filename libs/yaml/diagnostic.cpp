#include "libs/yaml/diagnostic.hpp"

namespace rcand::yaml {
namespace {

std::string join_diagnostics(const std::vector<ConfigDiagnostic>& diagnostics) {
  std::string out;
  for (const auto& d : diagnostics) {
    if (!out.empty()) out += '\n';
    out += d.format();
  }
  return out;
}

}  // namespace

std::string ConfigDiagnostic::format() const {
  std::string out = mark.file;
  if (mark.line > 0) out += ":" + std::to_string(mark.line) + ":" + std::to_string(mark.column);
  out += severity == Severity::Error ? ": error: " : ": warning: ";
  if (!key_path.empty()) out += key_path + ": ";
  out += message;
  return out;
}

ConfigError::ConfigError(std::vector<ConfigDiagnostic> diagnostics)
    : std::runtime_error(join_diagnostics(diagnostics)), diagnostics_(std::move(diagnostics)) {}

const std::vector<ConfigDiagnostic>& ConfigError::diagnostics() const noexcept { return diagnostics_; }

}  // namespace rcand::yaml
