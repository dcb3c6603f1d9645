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

}  // namespace rcand
