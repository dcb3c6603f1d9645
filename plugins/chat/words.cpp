#include "words.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <utility>

namespace rcand::plugins::chat {
namespace {

bool is_digit(char c) { return c >= '0' && c <= '9'; }
bool is_alpha(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); }

// Multi-byte spellings the grammar knows, replaced before the ASCII check.
constexpr std::array<std::pair<std::string_view, std::string_view>, 6> kSpellings{{
    {"\xC2\xB0", " degrees "},  // °
    {"\xE2\x80\x99", ""},       // ’ (what’s)
    {"\xE2\x80\x98", ""},       // ‘
    {"\xE2\x80\x9C", " "},      // “
    {"\xE2\x80\x9D", " "},      // ”
    {"\xE2\x80\x94", " "},      // —
}};

std::optional<double> digits(std::string_view token) {
  if (token.empty()) return std::nullopt;
  double value = 0.0;
  const char* first = token.data();
  const char* last = token.data() + token.size();
  std::string padded;  // from_chars wants a digit before the point: ".5" -> "0.5", "-.5" -> "-0.5"
  if (token.front() == '.' || (token.size() > 1 && token[0] == '-' && token[1] == '.')) {
    padded = std::string(token);
    padded.insert(token.front() == '-' ? 1 : 0, "0");
    first = padded.data();
    last = padded.data() + padded.size();
  }
  const auto [end, ec] = std::from_chars(first, last, value);
  if (ec != std::errc() || end != last || !std::isfinite(value)) return std::nullopt;
  return value;
}

constexpr std::array<std::string_view, 20> kSmall{
    "zero", "one",    "two",    "three",    "four",     "five",    "six",     "seven",     "eight",    "nine",
    "ten",  "eleven", "twelve", "thirteen", "fourteen", "fifteen", "sixteen", "seventeen", "eighteen", "nineteen"};
constexpr std::array<std::string_view, 8> kTens{"twenty", "thirty", "forty", "fifty", "sixty", "seventy", "eighty", "ninety"};

std::optional<int> small_word(std::string_view w) {
  for (std::size_t i = 0; i < kSmall.size(); ++i)
    if (kSmall[i] == w) return static_cast<int>(i);
  return std::nullopt;
}
std::optional<int> tens_word(std::string_view w) {
  for (std::size_t i = 0; i < kTens.size(); ++i)
    if (kTens[i] == w) return static_cast<int>(20 + 10 * i);
  return std::nullopt;
}

const std::string* at_or_null(const Tokens& t, std::size_t i) { return i < t.size() ? &t[i] : nullptr; }
bool is(const Tokens& t, std::size_t i, std::string_view w) { return i < t.size() && t[i] == w; }

// "twenty five", "one hundred and five", "seven": a whole number in words.
std::optional<Number> whole_words(const Tokens& t, std::size_t at) {
  std::size_t i = at;
  double value = 0.0;
  bool any = false;
  auto below_hundred = [&]() -> std::optional<double> {
    const std::string* w = at_or_null(t, i);
    if (!w) return std::nullopt;
    if (auto tens = tens_word(*w)) {
      ++i;
      if (const std::string* next = at_or_null(t, i);
          next && small_word(*next) && *small_word(*next) > 0 && *small_word(*next) < 10) {
        ++i;
        return *tens + *small_word(*next);
      }
      return *tens;
    }
    if (auto small = small_word(*w)) {
      ++i;
      return *small;
    }
    return std::nullopt;
  };
  if (auto first = below_hundred()) {
    value = *first;
    any = true;
  } else if (is(t, i, "a") && is(t, i + 1, "hundred")) {
    value = 1;
    ++i;
    any = true;
  }
  if (any && is(t, i, "hundred")) {
    ++i;
    value *= 100;
    std::size_t save = i;
    if (is(t, i, "and")) ++i;
    if (auto rest = below_hundred()) value += *rest;
    else i = save;
  }
  if (!any) return std::nullopt;
  return Number{value, i};
}

// "and a half", "and a quarter" after a whole number.
std::size_t add_fraction_tail(const Tokens& t, std::size_t i, double& value) {
  if (is(t, i, "and") && (is(t, i + 1, "a") || is(t, i + 1, "one"))) {
    if (is(t, i + 2, "half")) return value += 0.5, i + 3;
    if (is(t, i + 2, "quarter")) return value += 0.25, i + 3;
  }
  return i;
}

// "a", "an", "of a", "of an" after a fraction: "half a metre", "a quarter of a metre".
std::size_t skip_article_tail(const Tokens& t, std::size_t i) {
  if (is(t, i, "of")) ++i;
  if (is(t, i, "a") || is(t, i, "an")) ++i;
  return i;
}

}  // namespace

std::optional<Tokens> tokenize(std::string_view text) {
  std::string s(text);
  for (const auto& [from, to] : kSpellings)
    for (std::size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size()))
      s.replace(at, from.size(), to);
  for (unsigned char c : s)
    if (c >= 0x80) return std::nullopt;
  for (char& c : s) c = static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
  for (std::size_t at = s.find("e-stop"); at != std::string::npos; at = s.find("e-stop", at)) s.replace(at, 6, "estop");

  Tokens tokens;
  std::string current;
  auto flush = [&] {
    if (!current.empty()) tokens.push_back(std::move(current));
    current.clear();
  };
  for (std::size_t i = 0; i < s.size(); ++i) {
    const char c = s[i];
    const char prev = i > 0 ? s[i - 1] : ' ';
    const char next = i + 1 < s.size() ? s[i + 1] : ' ';
    if (c == '\'' || c == '`') continue;  // what's -> whats
    if (is_alpha(c) || is_digit(c)) {
      // A digit-letter boundary splits "1.5m" and "90deg"; letters then digits ("x1") too.
      if (!current.empty() && is_digit(c) != (is_digit(current.back()) || current.back() == '.' || current.back() == '-'))
        flush();
      current += c;
      continue;
    }
    if (c == '.' && is_digit(next) && (current.empty() || is_digit(current.back()) || current == "-")) {
      current += c;  // a decimal point: "1.5", ".5"
      continue;
    }
    if (c == '-' && (is_digit(next) || next == '.') && !is_alpha(prev) && !is_digit(prev)) {
      flush();
      current = "-";  // a minus sign: "x -1"
      continue;
    }
    flush();
    if (c == '%') tokens.emplace_back("percent");
  }
  flush();
  return tokens;
}

std::optional<Number> read_number(const Tokens& t, std::size_t at, bool (*unit_follows)(std::string_view)) {
  if (at >= t.size()) return std::nullopt;
  const std::string& w = t[at];
  if (auto value = digits(w)) {
    Number n{*value, at + 1};
    n.end = add_fraction_tail(t, n.end, n.value);
    return n;
  }
  // Fractions on their own: "half (a)", "a half", "a quarter (of a)", "three quarters (of a)".
  if (w == "half") return Number{0.5, skip_article_tail(t, at + 1)};
  if ((w == "a" || w == "one") && is(t, at + 1, "half")) return Number{0.5, skip_article_tail(t, at + 2)};
  if ((w == "a" || w == "one") && is(t, at + 1, "quarter")) return Number{0.25, skip_article_tail(t, at + 2)};
  if (w == "three" && is(t, at + 1, "quarters")) return Number{0.75, skip_article_tail(t, at + 2)};
  if (w == "a" && is(t, at + 1, "couple") && is(t, at + 2, "of")) return Number{2.0, at + 3};
  if (auto whole = whole_words(t, at)) {
    Number n = *whole;
    if (is(t, n.end, "point")) {  // "one point five": decimal digits spoken one by one
      double scale = 0.1;
      std::size_t i = n.end + 1;
      while (i < t.size() && small_word(t[i]) && *small_word(t[i]) < 10) {
        n.value += scale * *small_word(t[i]);
        scale /= 10;
        ++i;
      }
      if (i > n.end + 1) n.end = i;
    }
    n.end = add_fraction_tail(t, n.end, n.value);
    return n;
  }
  if ((w == "a" || w == "an") && unit_follows && at + 1 < t.size() && unit_follows(t[at + 1])) {
    Number n{1.0, at + 1};
    return n;
  }
  return std::nullopt;
}

std::size_t edit_distance(std::string_view a, std::string_view b, std::size_t cap) {
  const std::size_t n = a.size(), m = b.size();
  if ((n > m ? n - m : m - n) > cap) return cap + 1;
  std::vector<std::vector<std::size_t>> d(n + 1, std::vector<std::size_t>(m + 1));
  for (std::size_t i = 0; i <= n; ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= m; ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= n; ++i)
    for (std::size_t j = 1; j <= m; ++j) {
      const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return std::min(d[n][m], cap + 1);
}

}  // namespace rcand::plugins::chat
