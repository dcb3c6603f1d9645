#include "injection_scan.hpp"

#include <array>
#include <regex>
#include <utility>

namespace rcand::plugins::chat {
namespace {

// Lower case; letters and digits kept, every run of anything else one space; zero-width characters dropped so
// "ig\u200bnore" reads "ignore". `leet` also reads digits and symbols as the letters they imitate (1gn0re).
std::string normalize(std::string_view text, bool leet) {
  std::string out;
  out.reserve(text.size());
  bool space = true;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    // U+200B..U+200D, U+2060 (E2 80 8B..8D, E2 81 A0) and U+FEFF (EF BB BF): invisible, dropped.
    if (c == 0xE2 && i + 2 < text.size() &&
        ((static_cast<unsigned char>(text[i + 1]) == 0x80 && static_cast<unsigned char>(text[i + 2]) >= 0x8B &&
          static_cast<unsigned char>(text[i + 2]) <= 0x8D) ||
         (static_cast<unsigned char>(text[i + 1]) == 0x81 && static_cast<unsigned char>(text[i + 2]) == 0xA0))) {
      i += 2;
      continue;
    }
    if (c == 0xEF && i + 2 < text.size() && static_cast<unsigned char>(text[i + 1]) == 0xBB &&
        static_cast<unsigned char>(text[i + 2]) == 0xBF) {
      i += 2;
      continue;
    }
    char ch = static_cast<char>(c);
    if (ch >= 'A' && ch <= 'Z') ch = static_cast<char>(ch - 'A' + 'a');
    if (leet) {
      static constexpr std::array<std::pair<char, char>, 8> kLeet{
          {{'0', 'o'}, {'1', 'i'}, {'3', 'e'}, {'4', 'a'}, {'5', 's'}, {'7', 't'}, {'@', 'a'}, {'$', 's'}}};
      for (auto [from, to] : kLeet)
        if (ch == from) ch = to;
    }
    const bool word = (ch >= 'a' && ch <= 'z') || (ch >= '0' && ch <= '9');
    if (word) {
      out += ch;
      space = false;
    } else if (!space) {
      out += ' ';
      space = true;
    }
  }
  return out;
}

struct Rule {
  const char* name;
  std::regex pattern;
};

const std::vector<Rule>& rules() {
  static const std::vector<Rule> kRules = [] {
    const auto flags = std::regex::ECMAScript | std::regex::optimize;
    const std::string quantifiers =
        "(?:(?:all|any|the|your|my|of|previous|prior|above|earlier|preceding|these|those|"
        "former|existing|original|current|system|safety) )*";
    std::vector<Rule> r;
    r.push_back(
        {"override_instructions", std::regex("\\b(?:ignore|disregard|forget|override|bypass|skip|drop) " + quantifiers +
                                                 "(?:instructions?|rules?|prompts?|directives?|guidelines?|context|constraints?|"
                                                 "programming|restrictions?|policies|policy|orders?)\\b",
                                             flags)});
    r.push_back({"role_change", std::regex("\\b(?:you are now|from now on you|act as (?:a|an|if)|pretend (?:to be|you|that)|"
                                           "role ?play|new persona|you are no longer)\\b",
                                           flags)});
    r.push_back({"jailbreak", std::regex("\\b(?:jailbreak|jailbroken|developer mode|dan mode|do anything now|god mode|"
                                         "admin mode|sudo mode|unrestricted mode|no restrictions)\\b",
                                         flags)});
    r.push_back({"prompt_leak", std::regex("\\b(?:system prompt|(?:reveal|print|show|repeat|leak|output) (?:me )?(?:your|the) "
                                           "(?:system )?(?:prompt|instructions))\\b",
                                           flags)});
    r.push_back(
        {"new_instructions", std::regex("\\b(?:new|updated|real|actual|hidden) (?:instructions|orders|task|rules)\\b", flags)});
    r.push_back({"disable_safety", std::regex("\\b(?:disable|deactivate|turn off|switch off|override|bypass|ignore|remove|"
                                              "circumvent) (?:the |your |all |any )*(?:safety|e stop|estop|emergency stop|"
                                              "speed limits?|limits?|collision|obstacle|watchdog|geofence|bounds)\\b",
                                              flags)});
    return r;
  }();
  return kRules;
}

// Chat-template and role markers a model would read as a turn boundary; checked on the raw text.
constexpr std::array<std::string_view, 10> kMarkers{"<|im_start|>", "<|im_end|>",     "<|system|>", "<|endoftext|>",
                                                    "[inst]",       "[/inst]",        "<<sys>>",    "</s>",
                                                    "### system",   "### instruction"};

}  // namespace

InjectionVerdict scan_for_injection(std::string_view text) {
  std::string lower(text);
  for (char& c : lower) c = static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
  for (auto marker : kMarkers)
    if (lower.find(marker) != std::string::npos) return {true, "template_marker"};
  for (bool leet : {false, true}) {
    const std::string normalized = normalize(text, leet);
    for (const auto& rule : rules())
      if (std::regex_search(normalized, rule.pattern)) return {true, rule.name};
  }
  return {};
}

}  // namespace rcand::plugins::chat
