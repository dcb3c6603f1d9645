// What a YAML file loader reports: every problem with its file:line:column and the key at fault, errors and
// warnings alike, so a user fixes them all in one pass.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

namespace rcand::yaml {

// 1-based line and column; line 0 means the problem is about the file as a whole (missing, unreadable).
struct SourceMark {
  std::string file;
  int line = 0;
  int column = 0;
};

struct ConfigDiagnostic {
  enum class Severity { Error, Warning };
  Severity severity = Severity::Error;
  SourceMark mark;
  // The key at fault ("physics.wheel_circumference_m", "drivers[1].id"). For an unknown key it is the enclosing block
  // ("" at top level), because the unknown name itself is quoted in the message.
  std::string key_path;
  std::string message;
  // "file:line:column: error: key.path: message"; ":line:column" is left out when line is 0, "key.path: " when empty.
  std::string format() const;
};

// Thrown when the file has at least one error. Carries every error found, plus the warnings, sorted by position.
class ConfigError : public std::runtime_error {  // what() = all diagnostics formatted, one per line
 public:
  explicit ConfigError(std::vector<ConfigDiagnostic> diagnostics);
  const std::vector<ConfigDiagnostic>& diagnostics() const noexcept;

 private:
  std::vector<ConfigDiagnostic> diagnostics_;
};

}  // namespace rcand::yaml
