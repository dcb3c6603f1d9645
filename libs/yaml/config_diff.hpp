// What a config reload changed: the key paths whose values differ between two config documents.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace rcand {

// Dot-separated paths ("runtime.logging.level"), sorted. Mappings are compared key by key; anything else (a list such
// as drivers or runtime.auth.tokens, a scalar) is one value. A key present on one side only counts as changed.
std::vector<std::string> changed_keys(const nlohmann::json& before, const nlohmann::json& after);

// True when `path` is `prefix` or lies below it ("runtime.auth.tokens" is under "runtime.auth").
bool key_is_under(const std::string& path, const std::string& prefix);

}  // namespace rcand
