#include "libs/yaml/yaml_document.hpp"

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>

namespace rcand::yaml {
namespace {

using nlohmann::json;

// Aliases are expanded into plain JSON, so a small hostile file ("billion laughs") could otherwise ask for gigabytes.
constexpr std::size_t kMaxValues = 100000;
constexpr int kMaxDepth = 64;

// Thrown inside the converter to stop at a limit; the diagnostic is already recorded.
struct Abort {};

SourceMark to_mark(const std::string& file, const YAML::Mark& m) {
  if (m.line < 0) return SourceMark{file, 0, 0};
  return SourceMark{file, m.line + 1, m.column + 1};
}

ConfigDiagnostic error_at(SourceMark mark, std::string key_path, std::string message) {
  return ConfigDiagnostic{ConfigDiagnostic::Severity::Error, std::move(mark), std::move(key_path), std::move(message)};
}

// Returns the offset of the first byte that is not part of well-formed UTF-8, or npos. A string that is not UTF-8
// would make every later json::dump() throw, so it is refused up front.
std::size_t first_invalid_utf8(std::string_view s) {
  std::size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    std::size_t len = 0;
    std::uint32_t cp = 0;
    if (c < 0x80) {
      ++i;
      continue;
    }
    if ((c & 0xE0) == 0xC0) {
      len = 2;
      cp = c & 0x1F;
    } else if ((c & 0xF0) == 0xE0) {
      len = 3;
      cp = c & 0x0F;
    } else if ((c & 0xF8) == 0xF0) {
      len = 4;
      cp = c & 0x07;
    } else return i;
    if (i + len > s.size()) return i;
    for (std::size_t k = 1; k < len; ++k) {
      const auto cc = static_cast<unsigned char>(s[i + k]);
      if ((cc & 0xC0) != 0x80) return i;
      cp = (cp << 6) | (cc & 0x3F);
    }
    const bool overlong = (len == 2 && cp < 0x80) || (len == 3 && cp < 0x800) || (len == 4 && cp < 0x10000);
    if (overlong || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return i;
    i += len;
  }
  return std::string_view::npos;
}

SourceMark mark_of_offset(const std::string& file, std::string_view text, std::size_t offset) {
  int line = 1, column = 1;
  for (std::size_t i = 0; i < offset && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++line;
      column = 1;
    } else ++column;
  }
  return SourceMark{file, line, column};
}

const char* node_kind(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Sequence: return "a sequence";
    case YAML::NodeType::Map: return "a mapping";
    case YAML::NodeType::Scalar: return "a scalar";
    default: return "null";
  }
}

class Converter {
 public:
  Converter(const std::string& file, std::vector<ConfigDiagnostic>& diagnostics, std::map<std::string, SourceMark>& marks)
      : file_(file), diagnostics_(diagnostics), marks_(marks) {}

  json convert(const YAML::Node& node, const std::string& path, int depth) {
    if (++values_ > kMaxValues) {
      diagnostics_.push_back(
          error_at(to_mark(file_, node.Mark()), path,
                   "the document is too large (more than " + std::to_string(kMaxValues) + " values once aliases are expanded)"));
      throw Abort{};
    }
    if (depth > kMaxDepth) {
      diagnostics_.push_back(
          error_at(to_mark(file_, node.Mark()), path, "nesting is deeper than " + std::to_string(kMaxDepth) + " levels"));
      throw Abort{};
    }
    switch (node.Type()) {
      case YAML::NodeType::Scalar: return scalar(node);
      case YAML::NodeType::Sequence: {
        json array = json::array();
        std::size_t index = 0;
        for (const auto& item : node) {
          const std::string p = item_path(path, index++);
          marks_[p] = to_mark(file_, item.Mark());
          array.push_back(convert(item, p, depth + 1));
        }
        return array;
      }
      case YAML::NodeType::Map: {
        json object = json::object();
        for (auto it = node.begin(); it != node.end(); ++it) {
          // Copies, not references: `it->` yields a temporary proxy (Node copies are cheap shared handles).
          const YAML::Node key = it->first;
          const YAML::Node value = it->second;
          const SourceMark key_mark = to_mark(file_, key.Mark());
          if (!key.IsScalar()) {
            diagnostics_.push_back(error_at(key_mark, path, std::string("a key must be a plain name, found ") + node_kind(key)));
            continue;
          }
          const std::string& name = key.Scalar();
          if (name.empty()) {
            diagnostics_.push_back(error_at(key_mark, path, "a key must not be empty"));
            continue;
          }
          const std::string p = child_path(path, name);
          if (object.contains(name)) {
            diagnostics_.push_back(error_at(
                key_mark, p, "duplicate key '" + name + "'; it was first written at line " + std::to_string(marks_[p].line)));
            continue;
          }
          marks_[p] = key_mark;
          object[name] = convert(value, p, depth + 1);
        }
        return object;
      }
      case YAML::NodeType::Null:
      case YAML::NodeType::Undefined: break;
    }
    return nullptr;
  }

 private:
  static json scalar(const YAML::Node& node) {
    const std::string& tag = node.Tag();
    // yaml-cpp tags quoted and block scalars "!": they are text whatever they look like.
    if (tag == "!" || tag == "tag:yaml.org,2002:str") return node.Scalar();
    return resolve_plain_scalar(node.Scalar());
  }

  const std::string& file_;
  std::vector<ConfigDiagnostic>& diagnostics_;
  std::map<std::string, SourceMark>& marks_;
  std::size_t values_ = 0;
};

template <class Pred> bool all_of(std::string_view s, Pred pred) { return std::all_of(s.begin(), s.end(), pred); }

bool is_digit(char c) { return c >= '0' && c <= '9'; }

// Skips a run of digits from `i`; returns how many there were.
std::size_t skip_digits(std::string_view s, std::size_t& i) {
  const std::size_t start = i;
  while (i < s.size() && is_digit(s[i])) ++i;
  return i - start;
}

// [-+]?[0-9]+
bool is_decimal(std::string_view s) {
  std::size_t i = (!s.empty() && (s[0] == '-' || s[0] == '+')) ? 1 : 0;
  return skip_digits(s, i) > 0 && i == s.size();
}

// [-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)([eE][-+]?[0-9]+)?
bool is_float(std::string_view s) {
  std::size_t i = (!s.empty() && (s[0] == '-' || s[0] == '+')) ? 1 : 0;
  if (i < s.size() && s[i] == '.') {
    ++i;
    if (skip_digits(s, i) == 0) return false;
  } else {
    if (skip_digits(s, i) == 0) return false;
    if (i < s.size() && s[i] == '.') {
      ++i;
      skip_digits(s, i);
    }
  }
  if (i < s.size() && (s[i] == 'e' || s[i] == 'E')) {
    ++i;
    if (i < s.size() && (s[i] == '-' || s[i] == '+')) ++i;
    if (skip_digits(s, i) == 0) return false;
  }
  return i == s.size();
}

json parse_float(std::string_view text) {
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  double value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec == std::errc::result_out_of_range) {
    // Too large becomes infinite (refused later as "not a finite number"); too small is zero.
    const bool tiny = text.find("e-") != std::string_view::npos || text.find("E-") != std::string_view::npos;
    const bool negative = !text.empty() && text.front() == '-';
    if (tiny) return negative ? -0.0 : 0.0;
    return negative ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity();
  }
  if (ec != std::errc{} || end != text.data() + text.size()) return std::string(text);
  return value;
}

}  // namespace

json resolve_plain_scalar(const std::string& text) {
  if (text.empty() || text == "~" || text == "null" || text == "Null" || text == "NULL") return nullptr;
  if (text == "true" || text == "True" || text == "TRUE") return true;
  if (text == "false" || text == "False" || text == "FALSE") return false;
  if (is_decimal(text)) {
    std::string_view digits(text);
    if (digits.front() == '+') digits.remove_prefix(1);
    std::int64_t value = 0;
    auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
    if (ec == std::errc{} && end == digits.data() + digits.size()) return value;
    std::uint64_t big = 0;
    auto [end2, ec2] = std::from_chars(digits.data(), digits.data() + digits.size(), big);
    if (ec2 == std::errc{} && end2 == digits.data() + digits.size()) return big;
    return parse_float(text);
  }
  const bool is_octal = text.size() > 2 && text.starts_with("0o") &&
                        all_of(std::string_view(text).substr(2), [](char c) { return c >= '0' && c <= '7'; });
  const bool is_hex = text.size() > 2 && text.starts_with("0x") && all_of(std::string_view(text).substr(2), [](char c) {
                        return std::isxdigit(static_cast<unsigned char>(c)) != 0;
                      });
  if (is_octal || is_hex) {
    std::uint64_t value = 0;
    const char* first = text.data() + 2;
    const char* last = text.data() + text.size();
    auto [end, ec] = std::from_chars(first, last, value, is_octal ? 8 : 16);
    if (ec == std::errc{} && end == last) {
      if (value <= static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) return static_cast<std::int64_t>(value);
      return value;
    }
    return text;
  }
  if (is_float(text)) return parse_float(text);
  std::string_view unsigned_text(text);
  const bool negative = !unsigned_text.empty() && unsigned_text.front() == '-';
  if (!unsigned_text.empty() && (unsigned_text.front() == '-' || unsigned_text.front() == '+')) unsigned_text.remove_prefix(1);
  if (unsigned_text == ".inf" || unsigned_text == ".Inf" || unsigned_text == ".INF")
    return negative ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity();
  if (text == ".nan" || text == ".NaN" || text == ".NAN") return std::numeric_limits<double>::quiet_NaN();
  return text;
}

SourceMark nearest_mark(const std::map<std::string, SourceMark>& marks, const std::string& file, std::string key_path) {
  for (;;) {
    if (const auto it = marks.find(key_path); it != marks.end()) return it->second;
    if (key_path.empty()) return SourceMark{file, 0, 0};
    const auto cut = key_path.find_last_of(".[");
    key_path = cut == std::string::npos ? std::string{} : key_path.substr(0, cut);
  }
}

std::string child_path(const std::string& parent, std::string_view key) {
  if (parent.empty()) return std::string(key);
  std::string out;
  out.reserve(parent.size() + 1 + key.size());
  out.append(parent).append(".").append(key);
  return out;
}

std::string item_path(const std::string& parent, std::size_t index) { return parent + "[" + std::to_string(index) + "]"; }

// Counts the documents of a stream by their start events, and is never asked past the second: yaml-cpp 0.7's
// LoadAll never returns on some inputs (a lone "," makes the parser yield empty documents forever, found by
// tests/fuzz/rcan_yaml), so the stream is not read to its end.
class DocumentCounter final : public YAML::EventHandler {
 public:
  int count() const noexcept { return count_; }
  const YAML::Mark& second_start() const noexcept { return second_; }
  void OnDocumentStart(const YAML::Mark& mark) override {
    if (++count_ == 2) second_ = mark;
  }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t, const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}

 private:
  int count_ = 0;
  YAML::Mark second_ = YAML::Mark::null_mark();
};

YamlDocument yaml_to_json(std::string_view text, const std::string& display_name, std::vector<ConfigDiagnostic>& diagnostics) {
  YamlDocument result;
  if (const auto bad = first_invalid_utf8(text); bad != std::string_view::npos) {
    diagnostics.push_back(error_at(mark_of_offset(display_name, text, bad), "", "the file is not valid UTF-8 text"));
    return result;
  }

  DocumentCounter documents;
  YAML::Node root;
  try {
    std::istringstream stream{std::string(text)};
    YAML::Parser parser(stream);
    while (documents.count() < 2 && parser.HandleNextDocument(documents)) {
    }
    if (documents.count() == 1) root = YAML::Load(std::string(text));
  } catch (const YAML::Exception& e) {
    // e.msg is yaml-cpp's description without the position (we print our own); it never quotes the input.
    diagnostics.push_back(error_at(to_mark(display_name, e.mark), "", "YAML syntax error: " + e.msg));
    return result;
  } catch (const std::exception& e) {
    diagnostics.push_back(error_at(SourceMark{display_name, 0, 0}, "", std::string("cannot parse YAML: ") + e.what()));
    return result;
  }

  if (documents.count() == 0 || (documents.count() == 1 && root.IsNull())) {
    result.empty = true;
    diagnostics.push_back(error_at(SourceMark{display_name, 1, 1}, "",
                                   "the file is empty; expected a mapping with at least 'rcan_version' and 'metadata'"));
    return result;
  }
  if (documents.count() > 1) {
    diagnostics.push_back(error_at(to_mark(display_name, documents.second_start()), "",
                                   "a config file holds one YAML document; a second one starts here"));
    return result;
  }

  result.marks[""] = to_mark(display_name, root.Mark());
  try {
    Converter converter(display_name, diagnostics, result.marks);
    result.doc = converter.convert(root, "", 0);
  } catch (const Abort&) {
    return result;
  }
  // Key-level errors (duplicates, non-scalar keys) are recorded but leave a usable document, so validation still runs
  // and every problem is reported in one go.
  result.ok = true;
  return result;
}

}  // namespace rcand::yaml
