// YAML text -> nlohmann::json plus the source mark of every key: config files report file:line:column.
#pragma once

#include "libs/yaml/diagnostic.hpp"

#include <nlohmann/json.hpp>

#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace rcand::yaml {

struct YamlDocument {
  bool ok = false;     // false: `diagnostics` holds at least one error and `doc` is unusable
  bool empty = false;  // no document, or only comments (an error for a config file, nothing for a conf.d fragment)
  nlohmann::json doc;
  std::map<std::string, SourceMark> marks;  // key path -> mark; "" is the root node
};

// Plain scalars resolve as YAML 1.2 core schema (null, booleans, integers, floats, else string); quoted and block
// scalars stay strings. Syntax errors, duplicate keys, non-scalar keys, invalid UTF-8 and more than one document are
// appended to `diagnostics` as errors.
YamlDocument yaml_to_json(std::string_view text, const std::string& display_name, std::vector<ConfigDiagnostic>& diagnostics);

// How a plain (unquoted, untagged) scalar resolves; exposed for tests and hints.
nlohmann::json resolve_plain_scalar(const std::string& text);

// Where `key_path` was written, else the nearest written ancestor ("a.b[2].c" -> "a.b[2]" -> "a.b" -> "a" -> "");
// line 0 when nothing matches.
SourceMark nearest_mark(const std::map<std::string, SourceMark>& marks, const std::string& file, std::string key_path);

// "a.b" + "c" -> "a.b.c"; "" + "c" -> "c".
std::string child_path(const std::string& parent, std::string_view key);
// "a.b" + 2 -> "a.b[2]".
std::string item_path(const std::string& parent, std::size_t index);

}  // namespace rcand::yaml
