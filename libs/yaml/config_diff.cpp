#include "libs/yaml/config_diff.hpp"

#include <algorithm>

namespace rcand {
namespace {

void collect(const nlohmann::json& before, const nlohmann::json& after, const std::string& path, std::vector<std::string>& out) {
  if (before.is_object() && after.is_object()) {
    for (const auto& [key, value] : before.items()) {
      const std::string child = path.empty() ? key : path + "." + key;
      if (const auto it = after.find(key); it != after.end()) collect(value, *it, child, out);
      else out.push_back(child);
    }
    for (const auto& [key, value] : after.items())
      if (!before.contains(key)) out.push_back(path.empty() ? key : path + "." + key);
    return;
  }
  if (before != after) out.push_back(path.empty() ? "(document)" : path);
}

}  // namespace

std::vector<std::string> changed_keys(const nlohmann::json& before, const nlohmann::json& after) {
  std::vector<std::string> out;
  collect(before, after, "", out);
  std::sort(out.begin(), out.end());
  return out;
}

bool key_is_under(const std::string& path, const std::string& prefix) {
  return path == prefix ||
         (path.size() > prefix.size() && path.compare(0, prefix.size(), prefix) == 0 && path[prefix.size()] == '.');
}

}  // namespace rcand
