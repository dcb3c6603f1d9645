// The one table that describes every known key of a `.rcan.yaml` file (fluent-bit config_map style), and the
// validator that walks a document against it (internal to the config module).
#pragma once

#include "kernel/config/robot_config.hpp"

#include <nlohmann/json.hpp>

#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rcand::kernel::config_detail {

enum class ValueType { Any, String, Integer, Number, Boolean, Mapping, Sequence };

// An extra rule on a value that already has the right type: returns the problem, or "" when the value is fine.
using ValueCheck = std::string (*)(const nlohmann::json& value);

struct KeySpec {
  // Schema path: "physics.wheel_circumference_m"; "drivers[]" is any item of `drivers`, "runtime.capabilities.*" any key.
  std::string_view path = {};
  ValueType type = ValueType::Any;
  bool required = false;
  nlohmann::json default_value = nullptr;                        // null: no default
  std::optional<double> min = std::nullopt, max = std::nullopt;  // numbers; `min_exclusive` makes min a strict bound
  bool min_exclusive = false;
  std::vector<std::string_view> choices = {};  // strings
  bool ignore_case = false;                    // for `choices`
  bool open = false;                           // mappings: keys without a spec are accepted without a warning
  bool non_empty = false;                      // strings
  bool unique = false;                         // no two items of the enclosing sequence share the value
  bool secret = false;                         // never echo the value in a message
  std::string_view required_unless = {};       // a sibling key whose presence lifts `required`
  ValueCheck check = nullptr;
  std::string_view description = {};
};

const std::vector<KeySpec>& config_schema();
const KeySpec* find_spec(std::string_view schema_path);
// The table's default for `schema_path` (null json when it has none).
const nlohmann::json& schema_default(std::string_view schema_path);

// Appends an error or warning to `out` for every problem in `doc`.
void validate_config(const nlohmann::json& doc, const std::map<std::string, SourceMark>& marks, const std::string& file,
                     std::vector<ConfigDiagnostic>& out);

}  // namespace rcand::kernel::config_detail
