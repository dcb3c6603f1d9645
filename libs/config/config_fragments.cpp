#include "libs/config/config_fragments.hpp"

#include <algorithm>

namespace rcand::config {
namespace {

namespace fs = std::filesystem;
using Marks = std::map<std::string, SourceMark>;

bool under(const std::string& path, const std::string& prefix) {
  if (path.size() == prefix.size()) return path == prefix;
  return path.size() > prefix.size() && path.starts_with(prefix) && (path[prefix.size()] == '.' || path[prefix.size()] == '[');
}

// Replaces the marks at and under `path` in `into` by those of `from`.
void take_marks(Marks& into, const Marks& from, const std::string& path) {
  std::erase_if(into, [&](const auto& entry) { return under(entry.first, path); });
  for (auto it = from.lower_bound(path); it != from.end() && it->first.starts_with(path); ++it)
    if (under(it->first, path)) into.insert(*it);
}

void merge_mapping(nlohmann::json& base, const nlohmann::json& patch, const std::string& path, Marks& base_marks,
                   const Marks& patch_marks) {
  for (const auto& [key, value] : patch.items()) {
    const std::string child = yaml::child_path(path, key);
    if (value.is_null()) {  // RFC 7396: null removes
      base.erase(key);
      std::erase_if(base_marks, [&](const auto& entry) { return under(entry.first, child); });
    } else if (value.is_object()) {  // merged into what is there, or into an empty mapping (nulls in it drop out)
      if (!base.contains(key) || !base[key].is_object()) {
        base[key] = nlohmann::json::object();
        std::erase_if(base_marks, [&](const auto& entry) { return under(entry.first, child); });
        if (const auto own = patch_marks.find(child); own != patch_marks.end()) base_marks.insert(*own);
      }
      merge_mapping(base[key], value, child, base_marks, patch_marks);
    } else {
      base[key] = value;
      take_marks(base_marks, patch_marks, child);
    }
  }
}

}  // namespace

std::vector<fs::path> config_fragment_files(const fs::path& config_file) {
  const fs::path dir = config_file.parent_path() / "conf.d";
  std::vector<fs::path> files;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.starts_with('.') || it->path().extension() != ".yaml") continue;
    if (std::error_code type_ec; !it->is_regular_file(type_ec)) continue;
    files.push_back(it->path());
  }
  std::sort(files.begin(), files.end(), [](const fs::path& a, const fs::path& b) { return a.filename() < b.filename(); });
  return files;
}

void merge_config_fragment(yaml::YamlDocument& base, const yaml::YamlDocument& fragment, const std::string& fragment_name,
                           std::vector<ConfigDiagnostic>& diagnostics) {
  if (!fragment.doc.is_object()) {
    const auto root = fragment.marks.find("");
    diagnostics.push_back({ConfigDiagnostic::Severity::Error,
                           root != fragment.marks.end() ? root->second : SourceMark{fragment_name, 0, 0}, "",
                           std::string("a conf.d fragment must be a mapping of config keys, found ") + fragment.doc.type_name()});
    return;
  }
  if (!base.doc.is_object()) {  // RFC 7396: a patch over a non-mapping starts from {}; the old items' marks go too
    base.doc = nlohmann::json::object();
    std::erase_if(base.marks, [](const auto& entry) { return !entry.first.empty(); });
  }
  merge_mapping(base.doc, fragment.doc, "", base.marks, fragment.marks);
}

}  // namespace rcand::config
