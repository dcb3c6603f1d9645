#include "libs/manifest/manifest.hpp"

#include <fstream>
#include <optional>
#include <set>
#include <sstream>
#include <utility>

#include "rcand/sdk/contract/isolation.hpp"
#include "rcand/sdk/contract/plan.hpp"
#include "rcand/sdk/contract/settings.hpp"

namespace rcand {
namespace {

using nlohmann::json;

// Every error names the file and the field: "<file>: <field>: <what>".
class Fields {
 public:
  explicit Fields(const std::filesystem::path& file) : file_(file.string()) {}

  [[noreturn]] void fail(const std::string& field, const std::string& what) const {
    throw ManifestError(file_ + ": " + field + ": " + what);
  }

  const json& require(const json& object, const std::string& key, const std::string& field) const {
    const auto it = object.find(key);
    if (it == object.end()) fail(field, "required field is missing");
    return *it;
  }

  std::string string(const json& value, const std::string& field, bool allow_empty = false) const {
    if (!value.is_string()) fail(field, std::string("expected string, found ") + value.type_name());
    std::string text = value.get<std::string>();
    if (!allow_empty && text.empty()) fail(field, "must not be empty");
    return text;
  }

  int non_negative_int(const json& value, const std::string& field) const {
    if (!value.is_number_integer()) fail(field, std::string("expected integer, found ") + value.type_name());
    const auto number = value.get<long long>();
    if (number < 0 || number > 65535) fail(field, "expected an integer in [0, 65535], found " + value.dump());
    return static_cast<int>(number);
  }

  bool boolean(const json& value, const std::string& field) const {
    if (!value.is_boolean()) fail(field, std::string("expected boolean, found ") + value.type_name());
    return value.get<bool>();
  }

 private:
  std::string file_;
};

// A reverse-domain id or a capability/driver name: no spaces, slashes or other URL-hostile characters.
bool is_identifier(const std::string& text) {
  for (const char c : text) {
    const bool ok =
        (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' || c == '-';
    if (!ok) return false;
  }
  return !text.empty();
}

bool is_dotted_key(const std::string& key) {
  return is_identifier(key) && key.front() != '.' && key.back() != '.' && key.find("..") == std::string::npos;
}

// A driver's "implies": [{capabilities, when?, unless?, reads_as?}], what its presence implies when the robot's file
// lists no capabilities.
std::vector<DriverImplication> parse_implies(const Fields& f, const json& list, const ProvidedItem& item,
                                             const std::string& field) {
  if (item.kind != "driver") f.fail(field, "only a driver's presence implies capabilities");
  if (!list.is_array()) f.fail(field, std::string("expected array, found ") + list.type_name());
  std::vector<DriverImplication> implies;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string at = field + "[" + std::to_string(i) + "]";
    if (!list[i].is_object()) f.fail(at, std::string("expected object, found ") + list[i].type_name());
    for (const auto& [key, value] : list[i].items())
      if (key != "capabilities" && key != "when" && key != "unless" && key != "reads_as")
        f.fail(at + "." + key, "unknown key (expected capabilities, when, unless, reads_as)");
    DriverImplication implication;
    const json& names = f.require(list[i], "capabilities", at + ".capabilities");
    if (!names.is_array() || names.empty()) f.fail(at + ".capabilities", "expected a non-empty array of capability names");
    for (std::size_t n = 0; n < names.size(); ++n) {
      const std::string name_field = at + ".capabilities[" + std::to_string(n) + "]";
      implication.capabilities.push_back(f.string(names[n], name_field));
      if (!is_identifier(implication.capabilities.back())) f.fail(name_field, "not a capability name");
    }
    for (auto [key, into] : {std::pair{"when", &implication.when}, std::pair{"unless", &implication.unless}})
      if (const auto it = list[i].find(key); it != list[i].end() && !is_dotted_key(*into = f.string(*it, at + "." + key)))
        f.fail(at + "." + key, "expected a dotted config key such as \"physics.kinematics\", found '" + *into + "'");
    if (const auto it = list[i].find("reads_as"); it != list[i].end()) implication.reads_as = f.string(*it, at + ".reads_as");
    implies.push_back(std::move(implication));
  }
  return implies;
}

// One "provides" entry: a capability, or a driver (an actuating one names the interface it implements).
ProvidedItem parse_provided(const Fields& f, const json& entry, const std::string& field) {
  if (!entry.is_object()) f.fail(field, std::string("expected object, found ") + entry.type_name());
  ProvidedItem item;
  item.kind = f.string(f.require(entry, "kind", field + ".kind"), field + ".kind");
  if (item.kind != "capability" && item.kind != "driver")
    f.fail(field + ".kind", "expected \"capability\" or \"driver\", found \"" + item.kind + "\"");
  item.name = f.string(f.require(entry, "name", field + ".name"), field + ".name");
  if (!is_identifier(item.name))
    f.fail(field + ".name", "'" + item.name + "' is not a valid name (letters, digits, '.', '_', '-')");
  if (const auto it = entry.find("actuates"); it != entry.end()) item.actuates = f.boolean(*it, field + ".actuates");
  if (const auto it = entry.find("interface"); it != entry.end()) {
    if (item.kind != "driver") f.fail(field + ".interface", "only drivers implement an actuator interface");
    item.interface = f.string(*it, field + ".interface");
    if (!item.actuates) f.fail(field + ".interface", "only actuating drivers (\"actuates\": true) implement an interface");
  } else if (item.kind == "driver" && item.actuates) {
    f.fail(field + ".interface", "required for an actuating driver (for example \"differential_drive\")");
  }
  if (const auto it = entry.find("fail_safe"); it != entry.end()) item.fail_safe = f.string(*it, field + ".fail_safe");
  if (entry.contains("isolation") || entry.contains("isolation_needs")) {
    if (item.kind != "capability")
      f.fail(field + (entry.contains("isolation") ? ".isolation" : ".isolation_needs"),
             "only a capability runs in a process of its own");
    try {
      sdk::contract::isolation_of(entry, nullptr);
    } catch (const sdk::contract::SettingsError& e) {
      f.fail(field + "." + e.key(), e.problem());
    }
  }
  if (const auto it = entry.find("implies"); it != entry.end()) item.implies = parse_implies(f, *it, item, field + ".implies");
  try {
    sdk::contract::check_provided_item(entry, field);
  } catch (const sdk::contract::SettingsError& e) {
    f.fail(e.key(), e.problem());
  }
  item.entry = entry;
  return item;
}

// A capability's "declared_when": the dotted config key whose value `true` declares it (runtime.r2r.enabled).
std::optional<DeclaredWhen> parse_declared_when(const Fields& f, const json& entry, const ProvidedItem& item,
                                                const std::string& field) {
  const auto it = entry.find("declared_when");
  if (it == entry.end()) return std::nullopt;
  const std::string key = f.string(*it, field + ".declared_when");
  if (item.kind != "capability") f.fail(field + ".declared_when", "only a capability is declared by a config key");
  if (!is_dotted_key(key))
    f.fail(field + ".declared_when", "expected a dotted config key such as \"runtime.r2r.enabled\", found '" + key + "'");
  return DeclaredWhen{item.name, key};
}

}  // namespace

PluginManifest parse_manifest(const json& doc, const std::filesystem::path& file) {
  const Fields f(file);
  if (!doc.is_object()) f.fail("(document)", std::string("expected a JSON object, found ") + doc.type_name());

  PluginManifest m;
  std::error_code ec;
  m.file = std::filesystem::absolute(file, ec).lexically_normal();
  if (ec) m.file = file;

  m.id = f.string(f.require(doc, "id", "id"), "id");
  if (!is_identifier(m.id)) f.fail("id", "'" + m.id + "' is not a reverse-domain id (letters, digits, '.', '_', '-')");
  m.version = f.string(f.require(doc, "version", "version"), "version");

  const std::string library = f.string(f.require(doc, "library", "library"), "library");
  const std::filesystem::path library_path(library);
  if (library_path.is_absolute()) f.fail("library", "expected a path relative to the manifest's folder, found '" + library + "'");
  m.library = (m.file.parent_path() / library_path).lexically_normal();

  const json& abi = f.require(doc, "abi", "abi");
  if (!abi.is_object()) f.fail("abi", std::string("expected object {\"major\", \"minor\"}, found ") + abi.type_name());
  m.abi_major = f.non_negative_int(f.require(abi, "major", "abi.major"), "abi.major");
  m.abi_minor = f.non_negative_int(f.require(abi, "minor", "abi.minor"), "abi.minor");

  if (const auto it = doc.find("description"); it != doc.end()) m.description = f.string(*it, "description", true);

  const json& provides = f.require(doc, "provides", "provides");
  if (!provides.is_array()) f.fail("provides", std::string("expected array, found ") + provides.type_name());
  if (provides.empty()) f.fail("provides", "must list at least one capability or driver");
  std::set<std::pair<std::string, std::string>> seen;
  for (std::size_t i = 0; i < provides.size(); ++i) {
    const std::string field = "provides[" + std::to_string(i) + "]";
    ProvidedItem item = parse_provided(f, provides[i], field);
    if (!seen.emplace(item.kind, item.name).second) f.fail(field + ".name", item.kind + " '" + item.name + "' is listed twice");
    if (auto declared = parse_declared_when(f, provides[i], item, field)) m.declared_when.push_back(std::move(*declared));
    m.provides.push_back(std::move(item));
  }

  if (const auto it = doc.find("requires"); it != doc.end()) {
    if (!it->is_array()) f.fail("requires", std::string("expected array of interface names, found ") + it->type_name());
    for (std::size_t i = 0; i < it->size(); ++i) m.requires_.push_back(f.string((*it)[i], "requires[" + std::to_string(i) + "]"));
  }

  if (const auto it = doc.find("config"); it != doc.end()) {
    try {
      sdk::contract::check_settings_schema(*it, "config.");
    } catch (const sdk::contract::SettingsError& e) {
      throw ManifestError(file.string() + ": " + e.what());
    }
    m.config_schema = *it;
  }
  return m;
}

json settings_schema_of(const PluginManifest& m, std::string_view kind, std::string_view name) {
  const ProvidedItem* item = find_provided(m, kind, name);
  return item != nullptr && item->entry.contains("config") ? item->entry["config"] : m.config_schema;
}

const ProvidedItem* find_provided(const PluginManifest& m, std::string_view kind, std::string_view name) noexcept {
  for (const auto& item : m.provides)
    if (item.kind == kind && item.name == name) return &item;
  return nullptr;
}

PluginManifest load_manifest(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw ManifestError(file.string() + ": (file): cannot be read");
  std::ostringstream text;
  text << in.rdbuf();
  json doc;
  try {
    doc = json::parse(text.str());
  } catch (const json::parse_error& e) {
    // e.what() carries the byte offset and what was unexpected; strip the library's "[json.exception...]".
    std::string what = e.what();
    if (const auto pos = what.find("] "); what.rfind("[json.exception", 0) == 0 && pos != std::string::npos)
      what = what.substr(pos + 2);
    throw ManifestError(file.string() + ": (document): invalid JSON: " + what);
  }
  PluginManifest manifest = parse_manifest(doc, file);
  manifest.text = text.str();
  return manifest;
}

}  // namespace rcand
