// nlohmann::json -> YAML text a person would write: block mappings and lists, with a mapping or list of scalars kept
// on one line in flow style ({in1: 17, in2: 27}); a string that would read back as something else ("0x41", "true",
// "17") is quoted. Reading the text back with yaml_to_json gives the same JSON.
#pragma once

#include <nlohmann/json.hpp>

#include <string>

namespace rcand::yaml {

std::string json_to_yaml(const nlohmann::ordered_json& value);  // keys in the order written
std::string json_to_yaml(const nlohmann::json& value);

}  // namespace rcand::yaml
