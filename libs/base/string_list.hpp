// Lists of names as rcand's messages and records write them: joined with a separator, kept free of repeats.
#pragma once

#include <algorithm>
#include <string>
#include <string_view>
#include <vector>

namespace rcand {

inline std::string join(const std::vector<std::string>& items, std::string_view separator) {
  std::string out;
  for (const auto& item : items) {
    if (!out.empty()) out += separator;
    out += item;
  }
  return out;
}

// Appends `name` unless the list has it already.
inline void add_unique(std::vector<std::string>& names, std::string name) {
  if (std::find(names.begin(), names.end(), name) == names.end()) names.push_back(std::move(name));
}

}  // namespace rcand
