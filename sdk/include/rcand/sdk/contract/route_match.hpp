// How a request finds its row (rcand/sdk/contract/door.hpp): exact rows win, then the longest prefix, then a row of
// the request's own method over a "*" row. Any row type through a key function, so the kernel's Router (whose rows
// carry handlers) and the contract's capability route table match alike. Light on purpose: no JSON, no SDK types.
#pragma once

#include <algorithm>
#include <cstddef>
#include <iterator>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace rcand::sdk::contract {

// 0: `pattern` does not match `path`; otherwise larger is more specific (an exact row beats every prefix, a longer
// prefix a shorter one).
inline std::size_t path_specificity(std::string_view pattern, std::string_view path) noexcept {
  if (pattern.empty() || pattern.back() != '*') return pattern == path ? std::string_view::npos : 0;
  const std::string_view prefix = pattern.substr(0, pattern.size() - 1);
  return path.size() > prefix.size() && path.substr(0, prefix.size()) == prefix ? prefix.size() : 0;
}

struct RowKey {
  std::string_view method, path, action_type;
};
template <class Row> struct RowMatch {
  const Row* row = nullptr;          // null: no row for this method
  std::vector<std::string> allowed;  // the methods the path has, when row is null (empty: 404)
};

// The most specific pattern with a row for this method (or "*") wins: POST on a path whose exact row is GET-only
// falls through to a prefix row, so a capability's mount answers it (after authentication) rather than the table.
// Only rows of `action_type` take part (an empty one: the rows of no type). `key(row)` gives a row's RowKey; match()
// below is the table's own.
template <class Rows, class Key>
auto match_rows(const Rows& rows, Key key, std::string_view method, std::string_view path, std::string_view action_type = {}) {
  RowMatch<std::remove_cvref_t<decltype(*std::begin(rows))>> found;
  std::size_t found_specificity = 0, top = 0;
  int found_rank = 0;
  for (const auto& row : rows) {
    const RowKey k = key(row);
    const std::size_t s = k.action_type == action_type ? path_specificity(k.path, path) : 0;
    if (s == 0) continue;
    top = std::max(top, s);
    const int rank = k.method == method ? 2 : k.method == "*" ? 1 : 0;
    if (rank > 0 && (s > found_specificity || (s == found_specificity && rank > found_rank))) {
      found.row = &row;
      found_specificity = s;
      found_rank = rank;
    }
  }
  if (found.row != nullptr) return found;
  for (const auto& row : rows)
    if (top != 0 && key(row).action_type == action_type && path_specificity(key(row).path, path) == top)
      found.allowed.emplace_back(key(row).method);
  return found;
}
}  // namespace rcand::sdk::contract
