#include "libs/base/closest_match.hpp"

#include <algorithm>
#include <cctype>

namespace rcand {
namespace {

// Damerau-Levenshtein (optimal string alignment), case-insensitive.
std::size_t edit_distance(std::string_view a, std::string_view b) {
  auto lower = [](char c) { return static_cast<char>(std::tolower(static_cast<unsigned char>(c))); };
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t cost = lower(a[i - 1]) == lower(b[j - 1]) ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && lower(a[i - 1]) == lower(b[j - 2]) && lower(a[i - 2]) == lower(b[j - 1]))
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  }
  return d[a.size()][b.size()];
}

}  // namespace

std::optional<std::string> closest_match(std::string_view word, const std::vector<std::string>& candidates) {
  if (word.empty()) return std::nullopt;
  // Longer words tolerate more typos; a short one with two changes is a different word.
  const std::size_t limit = std::clamp<std::size_t>((word.size() + 1) / 3, 1, 3);
  std::optional<std::string> best;
  std::size_t best_distance = limit + 1;
  for (const auto& candidate : candidates) {
    const std::size_t distance = edit_distance(word, candidate);
    if (distance < best_distance && distance < candidate.size()) {
      best = candidate;
      best_distance = distance;
    }
  }
  if (best) return best;
  // A truncated or extended name ("wheel_circ", "warning" for "warn") is a plausible slip too.
  for (const auto& candidate : candidates) {
    const std::string_view shorter = word.size() < candidate.size() ? word : std::string_view(candidate);
    const std::string_view longer = word.size() < candidate.size() ? std::string_view(candidate) : word;
    if (shorter.size() >= 4 && edit_distance(shorter, longer.substr(0, shorter.size())) == 0) return candidate;
  }
  return std::nullopt;
}

}  // namespace rcand
