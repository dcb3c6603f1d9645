// Request bodies as JSON, through nlohmann's parser with a nesting limit (deeply nested input would make
// later recursive walks — dump, comparisons — exhaust the stack).
#pragma once

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <string_view>

namespace rcand {

inline constexpr int kMaxJsonDepth = 64;

struct JsonBody {
  nlohmann::json value;  // null for an empty body
  std::string error;     // non-empty when the body is not acceptable JSON
};

JsonBody parse_json_body(std::string_view text);

// True only for a JSON true at `key`: a plugin's or a peer's "running": "yes" is not true, and not an error either.
inline bool is_true(const nlohmann::json& object, const char* key) {
  if (!object.is_object()) return false;
  const auto found = object.find(key);
  return found != object.end() && found->is_boolean() && found->get<bool>();
}

}  // namespace rcand
