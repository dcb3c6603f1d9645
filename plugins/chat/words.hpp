// The grammar brain's word layer: an instruction turned into lower-case tokens, English numbers read from them
// ("1.5", "one and a half", "half a", "twenty-five", "a" before a unit), and the edit distance its typo
// correction uses. Pure functions, no state.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rcand::plugins::chat {

using Tokens = std::vector<std::string>;

// Lower-case ASCII tokens. Punctuation separates ("x=1, y=2" -> x 1 y 2), a digit-letter boundary too ("1.5m" -> 1.5 m),
// "°" reads "degrees", "%" "percent", apostrophes vanish ("what's" -> whats), "e-stop" is "estop". nullopt when the
// text holds other non-ASCII letters: the grammar brain reads English only.
std::optional<Tokens> tokenize(std::string_view text);

struct Number {
  double value = 0.0;
  std::size_t end = 0;  // the first token after the number
};
// The number starting at tokens[at]: digits ("-1.5"), words ("twenty five", "one hundred", "one point five"),
// fractions ("half", "a quarter", "three quarters", "one and a half"), with a trailing "a"/"an"/"of a" of
// "half a metre" consumed. "a"/"an" alone is 1 only when `unit_follows` says the next token is a unit.
std::optional<Number> read_number(const Tokens& tokens, std::size_t at, bool (*unit_follows)(std::string_view));

// Damerau-Levenshtein distance (adjacent swaps count 1), capped: anything above `cap` reads cap + 1.
std::size_t edit_distance(std::string_view a, std::string_view b, std::size_t cap);

}  // namespace rcand::plugins::chat
