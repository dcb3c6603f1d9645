#include "libs/yaml/diagnostic.hpp"

#include <algorithm>
#include <tuple>

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

// By position: files in the order they first appear (the config, then its fragments), then line and column; the
// order found is kept among equals. A reader fixes them top to bottom.
std::vector<ConfigDiagnostic> by_position(std::vector<ConfigDiagnostic> diagnostics) {
  std::vector<std::string> files;
  for (const auto& d : diagnostics)
    if (std::find(files.begin(), files.end(), d.mark.file) == files.end()) files.push_back(d.mark.file);
  const auto rank = [&files](const ConfigDiagnostic& d) {
    return std::tuple(std::find(files.begin(), files.end(), d.mark.file) - files.begin(), d.mark.line, d.mark.column);
  };
  std::stable_sort(diagnostics.begin(), diagnostics.end(), [&](const auto& a, const auto& b) { return rank(a) < rank(b); });
  return diagnostics;
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
    : std::runtime_error(join_diagnostics(diagnostics = by_position(std::move(diagnostics)))),
      diagnostics_(std::move(diagnostics)) {}

const std::vector<ConfigDiagnostic>& ConfigError::diagnostics() const noexcept { return diagnostics_; }

}  // namespace rcand::yaml
