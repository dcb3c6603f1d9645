// rcand/sdk/bounded_text.hpp, the one helper that quotes untrusted text back: test vectors for what is kept, what is
// replaced (C0, DEL, C1, bidi formatting, line separators, invalid UTF-8) and how a long text is cut.
#include <rcand/sdk/bounded_text.hpp>  // first: the header compiles on its own

#include <doctest/doctest.h>

#include <string>
#include <utility>
#include <vector>

using rcand::sdk::bounded_text;
using rcand::sdk::is_unsafe_code_point;
using rcand::sdk::kQuotedTextLimit;

namespace {

// True when `text` is well-formed UTF-8 with no code point bounded_text replaces.
bool clean(const std::string& text) { return bounded_text(text, text.size() + 64) == text; }

}  // namespace

TEST_CASE("bounded text: printable text, accents, CJK and emoji come back unchanged") {
  for (const std::string text :
       {"plain", "", "caf\xc3\xa9", "\xe6\x97\xa5\xe6\x9c\xac", "\xf0\x9f\xa4\x96 robot", "tab-free, quote \" and backslash \\",
        "\xc2\xa0"
        "nbsp",
        "\xef\xbb\xbf"
        "bom"}) {
    CAPTURE(text);
    CHECK(bounded_text(text) == text);
  }
}

TEST_CASE("bounded text: control and formatting characters become '?', one per character") {
  const std::vector<std::pair<std::string, std::string>> vectors{
      {"a\nb\x01"
       "c",
       "a?b?c"},                                                     // C0
      {std::string("nul\0x", 5), "nul?x"},                           // NUL
      {"del\x7f", "del?"},                                           // DEL
      {"esc\x1b[31mred", "esc?[31mred"},                             // ESC: the sequence's printable rest stays, harmless
      {"c1 \xc2\x80 \xc2\x85 \xc2\x9b \xc2\x9f", "c1 ? ? ? ?"},      // C1: PAD, NEL, CSI, APC
      {"\xe2\x80\xaegol eht", "?gol eht"},                           // U+202E RIGHT-TO-LEFT OVERRIDE
      {"\xe2\x80\xaa\xe2\x80\xab\xe2\x80\xac\xe2\x80\xad", "????"},  // U+202A-U+202D
      {"\xe2\x81\xa6\xe2\x81\xa7\xe2\x81\xa8\xe2\x81\xa9", "????"},  // U+2066-U+2069 isolates
      {"\xe2\x80\x8e\xe2\x80\x8f\xd8\x9c", "???"},                   // LRM, RLM, ALM
      {"line\xe2\x80\xa8para\xe2\x80\xa9", "line?para?"},            // U+2028, U+2029
  };
  for (const auto& in_out_case : vectors) {
    const auto& in = in_out_case.first;  // clang 14: CAPTURE's lambda cannot capture a structured binding
    const auto& out = in_out_case.second;
    CAPTURE(in);
    CHECK(bounded_text(in) == out);
  }
  // Neighbours of the replaced ranges are text.
  CHECK(bounded_text("\xc2\xa0\xe2\x80\x8d\xe2\x80\xaf\xe2\x81\xa5\xe2\x81\xaa") ==
        "\xc2\xa0\xe2\x80\x8d\xe2\x80\xaf\xe2\x81\xa5\xe2\x81\xaa");
  CHECK_FALSE(is_unsafe_code_point(0x20));
  CHECK(is_unsafe_code_point(0x9F));
  CHECK_FALSE(is_unsafe_code_point(0xA0));
  CHECK_FALSE(is_unsafe_code_point(0x2027));
  CHECK(is_unsafe_code_point(0x2028));
  CHECK(is_unsafe_code_point(0x202E));
  CHECK_FALSE(is_unsafe_code_point(0x202F));
}

TEST_CASE("bounded text: invalid UTF-8 becomes '?' byte by byte") {
  const std::vector<std::pair<std::string, std::string>> vectors{
      {"bad \xff\xfe utf8", "bad ?? utf8"},
      {"\xc0\xaf", "??"},            // overlong '/'
      {"\xe0\x80\xaf", "???"},       // overlong, 3 bytes
      {"\xed\xa0\x80", "???"},       // a surrogate (U+D800)
      {"\xf4\x90\x80\x80", "????"},  // beyond U+10FFFF
      {"\xf5\x80\x80\x80", "????"},  // no such lead byte
      {"cut \xe2\x82", "cut ??"},    // a sequence cut short at the end
      {"\xe2\x82x", "??x"},          // ... or in the middle
      {"\x80", "?"},                 // a lone continuation byte
  };
  for (const auto& in_out_case : vectors) {
    const auto& in = in_out_case.first;  // clang 14: CAPTURE's lambda cannot capture a structured binding
    const auto& out = in_out_case.second;
    CAPTURE(in);
    CHECK(bounded_text(in) == out);
  }
}

TEST_CASE("bounded text: a long text is cut at a character boundary to at most the bound, naming what was left out") {
  const std::string megabyte(1 << 20, 'x');
  const std::string cut = bounded_text(megabyte);
  CHECK(cut.size() <= kQuotedTextLimit);
  CHECK(cut.ends_with(" bytes)"));
  const std::size_t kept = cut.find("...(+");
  REQUIRE(kept != std::string::npos);
  CHECK(cut.substr(kept) == "...(+" + std::to_string(megabyte.size() - kept) + " bytes)");

  std::string accents;
  for (int i = 0; i < 150; ++i) accents += "\xc3\xa9";  // é, two bytes each
  const std::string reason = bounded_text(accents);
  CHECK(reason.size() <= kQuotedTextLimit);
  CHECK(clean(reason));                         // never half a character
  CHECK(bounded_text(reason, 1000) == reason);  // what came out is safe: a second pass changes nothing

  std::string emoji;
  for (int i = 0; i < 100; ++i) emoji += "\xf0\x9f\xa4\x96";
  for (std::size_t bound : {32u, 33u, 34u, 35u, 64u, 200u}) {
    CAPTURE(bound);
    const std::string out = bounded_text(emoji, bound);
    CHECK(out.size() <= bound);
    CHECK(clean(out));
  }
  CHECK(bounded_text(std::string(200, 'y')) == std::string(200, 'y'));  // exactly the bound: kept whole
  CHECK(bounded_text(std::string(201, 'y')).size() <= 200);
  CHECK(bounded_text("short", 1).size() == 5);  // bounds below 32 are 32
}

TEST_CASE("bounded text: a megabyte of controls and overrides is 200 safe bytes") {
  std::string hostile;
  while (hostile.size() < (1u << 20)) hostile += "\x1b[2J\xe2\x80\xae\xc2\x9b\r\n";
  const std::string out = bounded_text(hostile);
  CHECK(out.size() <= kQuotedTextLimit);
  CHECK(clean(out));
  CHECK(out.find('\x1b') == std::string::npos);
  CHECK(out.find("\xe2\x80\xae") == std::string::npos);
}
