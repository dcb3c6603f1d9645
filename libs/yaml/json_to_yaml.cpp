#include "libs/yaml/json_to_yaml.hpp"

#include <yaml-cpp/yaml.h>

#include "libs/yaml/yaml_document.hpp"

namespace rcand::yaml {
namespace {

using ojson = nlohmann::ordered_json;

bool all_scalars(const ojson& value) {
  for (const auto& item : value)
    if (item.is_structured()) return false;
  return value.size() <= 8;
}

void emit(YAML::Emitter& out, const ojson& value) {
  switch (value.type()) {
    case ojson::value_t::object:
      out << (all_scalars(value) ? YAML::Flow : YAML::Block) << YAML::BeginMap;
      for (const auto& [key, item] : value.items()) {
        out << YAML::Key << key << YAML::Value;
        emit(out, item);
      }
      out << YAML::EndMap;
      return;
    case ojson::value_t::array:
      out << (all_scalars(value) ? YAML::Flow : YAML::Block) << YAML::BeginSeq;
      for (const auto& item : value) emit(out, item);
      out << YAML::EndSeq;
      return;
    case ojson::value_t::string: {
      const std::string text = value.get<std::string>();
      // Plain when it reads back as this very string, quoted otherwise ("0x41" would be the integer 65).
      if (const auto read = resolve_plain_scalar(text); read.is_string() && read.get<std::string>() == text) out << text;
      else out << YAML::DoubleQuoted << text;
      return;
    }
    case ojson::value_t::null: out << YAML::Null; return;
    case ojson::value_t::boolean: out << value.get<bool>(); return;
    default: out << value.dump(); return;  // numbers exactly as JSON writes them
  }
}

}  // namespace

std::string json_to_yaml(const nlohmann::json& value) { return json_to_yaml(ojson::parse(value.dump())); }

std::string json_to_yaml(const ojson& value) {
  YAML::Emitter out;
  out.SetIndent(2);
  out.SetSeqFormat(YAML::Block);
  emit(out, value);
  return std::string(out.c_str()) + "\n";
}

}  // namespace rcand::yaml
