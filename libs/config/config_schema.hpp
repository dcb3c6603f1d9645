// The one table that describes every known key of a `.rcan.yaml` file (fluent-bit config_map style), the validator
// that walks a document against it, and the door through which a service's own block of keys joins it
// (ConfigFragment: runtime.r2r is services/r2r's), so every key is checked once, by one engine, with file:line:column.
#pragma once

#include "libs/config/robot_config.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rcand::config::detail {

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
  std::string_view required_if = {};           // a sibling boolean key whose `true` makes this key required
  ValueCheck check = nullptr;
  std::string_view description = {};
};

// Every row: the kernel's table, then each linked service's fragment, in registration order.
const std::vector<const KeySpec*>& config_schema();
const KeySpec* find_spec(std::string_view schema_path);
// The table's default for `schema_path` (null json when it has none).
const nlohmann::json& schema_default(std::string_view schema_path);

// Runs every fragment's FragmentFileCheck on its block of `doc` (already validated), appending an error per problem.
void check_fragment_files(const nlohmann::json& doc, const std::map<std::string, SourceMark>& marks, const std::string& file,
                          const std::filesystem::path& base_dir, std::vector<ConfigDiagnostic>& out);

// Appends an error or warning to `out` for every problem in `doc`.
void validate_config(const nlohmann::json& doc, const std::map<std::string, SourceMark>& marks, const std::string& file,
                     std::vector<ConfigDiagnostic>& out);

// The major version of an `rcan_version` value ("1.3" -> 1, "v2.1.0" -> 2, "1.0.0-alpha" -> 1); nullopt when it is
// not a version.
std::optional<int> rcan_major_version(std::string_view text) noexcept;

// A role name as auth reads it (GUEST ... CREATOR, any case); for rows of any fragment that name a role.
std::string check_role(const nlohmann::json& value);

}  // namespace rcand::config::detail

namespace rcand::config {

using detail::KeySpec;
using detail::ValueType;

// A service's own keys, under a block the kernel's table declares as an open mapping (runtime.r2r). A fragment is a
// static object in the service's library: it registers itself before main, so the loader, --check-config and a
// SIGHUP reload check its keys like the kernel's, while the kernel never names the service. Registering after the
// first validation is a programming error (std::logic_error).
// What a fragment checks beyond its keys' values, with the config file's directory: the files its keys name (a peers
// file parses, its keys decode). Runs after a file's keys passed the table, at start, --check-config and each SIGHUP
// reload; returns {key path, problem} for each problem (the key path locates it in the config file).
using FragmentFileCheck = std::vector<std::pair<std::string, std::string>> (*)(const nlohmann::json& block,
                                                                               const std::filesystem::path& base_dir);

class ConfigFragment {
 public:
  explicit ConfigFragment(std::vector<KeySpec> rows);
  // The same, with `files` run on the value at `block_path` (a plain path such as "runtime.r2r") when it is present.
  ConfigFragment(std::vector<KeySpec> rows, std::string_view block_path, FragmentFileCheck files);
  ConfigFragment(const ConfigFragment&) = delete;
  ConfigFragment& operator=(const ConfigFragment&) = delete;

  const std::vector<KeySpec>& rows() const noexcept { return rows_; }
  // The same validation for `block`, the value at `schema_path` (a plain path such as "runtime.r2r") read outside a
  // config file: throws std::invalid_argument "<key path>: <problem>" for its first error.
  void check(const nlohmann::json& block, std::string_view schema_path) const;

 private:
  std::vector<KeySpec> rows_;
};

}  // namespace rcand::config
