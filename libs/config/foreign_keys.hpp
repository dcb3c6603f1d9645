// Keys that configs written for other RCAN runtimes, or for newer RCAN versions, carry and rcand (RCAN 1.3) does not
// implement. The validator ignores them and lists them all in one warning; knowing them also keeps a foreign key
// that happens to look like a misspelling of one of rcand's (`safety.watchdog`, `safety.max_linear_speed_mps`) from
// being refused as a typo.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <string_view>
#include <vector>

namespace rcand::config::detail {

struct ForeignKey {
  enum class Origin { NewerRcan, OtherRuntime };
  std::string_view path;  // dotted key path as written ("safety.watchdog")
  Origin origin = Origin::OtherRuntime;
  std::string_view rcand_reads = {};  // the rcand key with the nearest meaning, when there is one
};

// The catalogue entry for `key_path` (a plain dotted path, no list indices), or nullptr.
const ForeignKey* find_foreign_key(std::string_view key_path) noexcept;

}  // namespace rcand::config::detail

namespace rcand::config {

// A key of a drivers[] entry that other runtimes write and no plugin of rcand's reads unless its settings schema
// names it ("link_id", "frequency"): the plugin settings check ignores it with a warning instead of refusing it.
bool is_foreign_driver_key(std::string_view key) noexcept;

// Takes out of `settings` (a plugin instance's, configured at `path`: "drivers[2]", "camera") the keys other runtimes
// write there that the plugin's settings schema `properties` do not name, and returns their names.
std::vector<std::string> take_foreign_settings(nlohmann::json& settings, const nlohmann::json& properties, bool driver_entry,
                                               const std::string& path);

}  // namespace rcand::config
