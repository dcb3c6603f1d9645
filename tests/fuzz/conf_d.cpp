// libFuzzer target: conf.d drop-in fragments over a robot config (libs/config/config_fragments.cpp), as rcand loads
// them: the input is the main file's text and up to three fragments, separated by NUL bytes (never valid in YAML).
// Invariants:
//  - merging one fragment (merge_config_fragment) gives exactly RFC 7396's JSON Merge Patch of the two documents
//    (nlohmann::json::merge_patch is the reference), and every mark left names a key that exists, in the main file
//    or the fragment; every value the fragment wrote keeps the fragment's own file:line:column;
//  - the whole load (parse_robot_config with the fragments) throws only ConfigError, carrying an error; every
//    diagnostic names one of the files and a line inside that file (or 0, the whole file); none is the "internal
//    error" that means validation and the typed extraction disagree; an accepted config names its robot.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_check.hpp"
#include "libs/config/config_fragments.hpp"
#include "libs/config/robot_config.hpp"
#include "libs/yaml/yaml_document.hpp"

namespace {

namespace yaml = rcand::yaml;
using nlohmann::json;

constexpr std::size_t kMaxParts = 4;  // the main file and three fragments

// Every key path the document holds, spelled as the YAML loader spells marks ("a.b[2].c"; "" is the root).
void paths_of(const json& node, const std::string& at, std::set<std::string>& out) {
  out.insert(at);
  if (node.is_object())
    for (const auto& [key, value] : node.items()) paths_of(value, yaml::child_path(at, key), out);
  else if (node.is_array())
    for (std::size_t i = 0; i < node.size(); ++i) paths_of(node[i], yaml::item_path(at, i), out);
}

// The paths of the values a patch writes: its non-null leaves (a mapping merges, null removes).
void written_by(const json& patch, const std::string& at, std::vector<std::string>& out) {
  for (const auto& [key, value] : patch.items()) {
    const std::string child = yaml::child_path(at, key);
    if (value.is_object()) written_by(value, child, out);
    else if (!value.is_null()) out.push_back(child);
  }
}

std::string dump(const json& value) { return value.dump(-1, ' ', false, json::error_handler_t::replace); }

void check_merge(const std::string& base_text, const std::string& fragment_text) {
  std::vector<yaml::ConfigDiagnostic> diagnostics;
  yaml::YamlDocument base = yaml::yaml_to_json(base_text, "base.rcan.yaml", diagnostics);
  const yaml::YamlDocument fragment = yaml::yaml_to_json(fragment_text, "conf.d/50-fuzz.yaml", diagnostics);
  if (!base.ok || !fragment.ok) return;
  json expected = base.doc.is_object() ? base.doc : json::object();
  const std::size_t before = diagnostics.size();
  rcand::config::merge_config_fragment(base, fragment, "conf.d/50-fuzz.yaml", diagnostics);
  if (!fragment.doc.is_object()) {
    RCAND_FUZZ_CHECK(diagnostics.size() == before + 1, "a fragment that is not a mapping is one error");
    return;
  }
  RCAND_FUZZ_CHECK(diagnostics.size() == before, "a mapping merges without an error");
  expected.merge_patch(fragment.doc);
  // Compared as text: YAML's .nan is a NaN, which no JSON value equals, itself included.
  RCAND_FUZZ_CHECK(dump(base.doc) == dump(expected), "a fragment merges as an RFC 7396 merge patch");

  std::set<std::string> paths;
  paths_of(base.doc, "", paths);
  for (const auto& [path, mark] : base.marks) {
    RCAND_FUZZ_CHECK(paths.count(path) == 1, "a mark names a key the merged config holds");
    RCAND_FUZZ_CHECK(mark.file == "base.rcan.yaml" || mark.file == "conf.d/50-fuzz.yaml", "a mark names one of the files");
  }
  std::vector<std::string> written;
  written_by(fragment.doc, "", written);
  for (const auto& path : written) {
    if (!fragment.marks.count(path)) continue;
    const auto it = base.marks.find(path);
    RCAND_FUZZ_CHECK(it != base.marks.end() && it->second.file == "conf.d/50-fuzz.yaml",
                     "a value a fragment wrote keeps the fragment's mark");
  }
}

void check_load(const std::string& base_text, const std::vector<rcand::config::ConfigFragmentText>& fragments) {
  std::map<std::string, int> lines{
      {"fuzz.rcan.yaml", static_cast<int>(std::count(base_text.begin(), base_text.end(), '\n')) + 1}};
  for (const auto& f : fragments) lines[f.display_name] = static_cast<int>(std::count(f.text.begin(), f.text.end(), '\n')) + 1;
  try {
    const auto loaded = rcand::config::parse_robot_config(base_text, "fuzz.rcan.yaml", "/nonexistent-fuzz-dir", {}, fragments);
    RCAND_FUZZ_CHECK(!loaded.config.robot_name.empty(), "an accepted config names the robot");
    for (const auto& warning : loaded.warnings)
      RCAND_FUZZ_CHECK(warning.severity == yaml::ConfigDiagnostic::Severity::Warning, "a warning is a warning");
  } catch (const yaml::ConfigError& error) {
    const auto& diagnostics = error.diagnostics();
    RCAND_FUZZ_CHECK(std::any_of(diagnostics.begin(), diagnostics.end(),
                                 [](const auto& d) { return d.severity == yaml::ConfigDiagnostic::Severity::Error; }),
                     "a ConfigError carries an error");
    for (const auto& d : diagnostics) {
      const auto file = lines.find(d.mark.file);
      RCAND_FUZZ_CHECK(file != lines.end(), "a diagnostic names the main file or a fragment");
      RCAND_FUZZ_CHECK(d.mark.line >= 0 && d.mark.line <= file->second, "a diagnostic's line is inside its file");
      RCAND_FUZZ_CHECK(d.message.rfind("internal error while reading the validated config", 0) != 0,
                       "validation and extraction agree (no internal error)");
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  std::vector<std::string> parts;
  std::size_t start = 0;
  for (;;) {
    const std::size_t nul = input.find('\0', start);
    if (nul == std::string_view::npos || parts.size() + 1 == kMaxParts) {
      parts.emplace_back(input.substr(start));
      break;
    }
    parts.emplace_back(input.substr(start, nul - start));
    start = nul + 1;
  }
  const std::string& base = parts.front();
  std::vector<rcand::config::ConfigFragmentText> fragments;
  for (std::size_t i = 1; i < parts.size(); ++i)
    fragments.push_back({parts[i], "/etc/rcand/conf.d/" + std::to_string(i) + "0-fuzz.yaml"});
  if (!fragments.empty()) check_merge(base, fragments.front().text);
  check_load(base, fragments);
  return 0;
}
