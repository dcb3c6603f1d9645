// "Did you mean ...?": the candidate a misspelled name most plausibly meant, for config keys, capability names and
// swarm fields alike.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rcand {

// The closest candidate within a few edits (more for longer words), or one the word truncates or extends;
// nullopt when nothing is plausible.
std::optional<std::string> closest_match(std::string_view word, const std::vector<std::string>& candidates);

}  // namespace rcand
