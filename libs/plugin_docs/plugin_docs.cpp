#include "libs/plugin_docs/plugin_docs.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <tuple>

#include "libs/yaml/json_to_yaml.hpp"
#include "rcand/sdk/contract/claims.hpp"

namespace rcand::plugin_docs {
namespace {

using ojson = nlohmann::ordered_json;

// One thing a manifest provides.
struct Item {
  const ManifestText* manifest;
  std::string kind, name;  // "driver" or "capability"; protocol or capability name
  ojson entry;             // the "provides" entry
};

std::vector<Item> all_items(const std::vector<ManifestText>& manifests) {
  std::vector<Item> items;
  for (const auto& m : manifests)
    for (const auto& entry : m.document.value("provides", ojson::array()))
      if (entry.is_object()) items.push_back({&m, entry.value("kind", ""), entry.value("name", ""), entry});
  // Drivers first, then capabilities, each by name.
  std::stable_sort(items.begin(), items.end(), [](const Item& a, const Item& b) {
    return std::make_tuple(a.kind != "driver", a.name) < std::make_tuple(b.kind != "driver", b.name);
  });
  return items;
}

std::vector<Item> items_named(const std::vector<ManifestText>& manifests, const std::string& id) {
  std::vector<Item> out;
  for (auto& item : all_items(manifests))
    if (id.empty() || item.name == id || item.manifest->document.value("id", "") == id) out.push_back(std::move(item));
  return out;
}

ojson settings_schema(const Item& item) {
  if (item.entry.contains("config")) return item.entry["config"];
  return item.manifest->document.value("config", ojson::object());
}

ojson object_schema(const ojson& config) {
  if (config.contains("type") && config["type"].is_string()) return config;
  ojson root = ojson::object();
  root["type"] = "object";
  root["properties"] = config;
  return root;
}

// node[key] when it is an object, else an empty one (never a temporary: items() of one would dangle).
const ojson& object_at(const ojson& node, const char* key) {
  static const ojson kEmpty = ojson::object();
  const auto it = node.find(key);
  return it != node.end() && it->is_object() ? *it : kEmpty;
}

std::string text_of(const ojson& value) { return value.is_string() ? value.get<std::string>() : value.dump(); }

std::string joined(const std::vector<std::string>& parts, const std::string& separator) {
  std::string out;
  for (const auto& part : parts) out += (out.empty() ? "" : separator) + part;
  return out;
}

std::string def_name(const ojson& node) {
  const auto ref = node.find("$ref");
  if (ref == node.end() || !ref->is_string()) return {};
  const std::string text = ref->get<std::string>();
  return text.starts_with("#/$defs/") ? text.substr(8) : std::string();
}

// "Motor {in1, in2, enable?, ...}" -> "Motor"; a form without a title is "form N".
std::string form_label(const ojson& branch, std::size_t index) {
  const std::string title = branch.value("title", "");
  if (title.empty()) return "form " + std::to_string(index + 1);
  return title.substr(0, title.find(" {"));
}

std::vector<std::string> required_names(const ojson& node, const ojson& defs) {
  std::vector<std::string> names;
  for (const auto& name : node.value("required", ojson()).is_array() ? node["required"] : ojson::array()) names.push_back(name);
  for (const auto& [name, property] : object_at(node, "properties").items()) {
    const std::string def = def_name(property);
    const ojson& target = !def.empty() && defs.contains(def) ? defs[def] : property;
    if (property.value("required", ojson()) == true || (target.value("required", ojson()) == true)) names.push_back(name);
  }
  return names;
}

struct Row {
  std::string name, type, fallback, range, required, description, example;
};

// The first value `name` ("channels.left.in1", "servos[].id", "brains.<name>.url") takes in `value`, an example.
const ojson* value_at(const ojson& value, std::string_view name) {
  if (name.empty()) return &value;
  const auto end = name.find('.');
  std::string_view segment = name.substr(0, end);
  const std::string_view rest = end == std::string_view::npos ? std::string_view() : name.substr(end + 1);
  const bool each = segment.ends_with("[]");
  if (each) segment.remove_suffix(2);
  std::optional<std::size_t> position;  // "resolution[1]": the item at that place of a positional list
  if (const auto open = segment.rfind('['); !each && open != std::string_view::npos && segment.ends_with("]")) {
    std::size_t index = 0;
    const auto digits = segment.substr(open + 1, segment.size() - open - 2);
    const auto [end_of, error] = std::from_chars(digits.data(), digits.data() + digits.size(), index);
    if (error == std::errc() && end_of == digits.data() + digits.size() && !digits.empty()) {
      position = index;
      segment = segment.substr(0, open);
    }
  }
  std::vector<const ojson*> candidates;
  if (!value.is_object()) return nullptr;
  if (segment == "<name>") {
    for (const auto& [key, child] : value.items()) candidates.push_back(&child);
  } else if (const auto it = value.find(std::string(segment)); it != value.end()) {
    candidates.push_back(&*it);
  }
  for (const ojson* candidate : candidates) {
    if (position) {
      if (candidate->is_array() && *position < candidate->size())
        if (const ojson* found = value_at((*candidate)[*position], rest)) return found;
    } else if (!each) {
      if (const ojson* found = value_at(*candidate, rest)) return found;
    } else if (candidate->is_array()) {
      for (const auto& element : *candidate)
        if (const ojson* found = value_at(element, rest)) return found;
    }
  }
  return nullptr;
}

// The first value a key named `key` takes anywhere in `value` (for a definition's table, used at several places).
const ojson* value_of_key(const ojson& value, const std::string& key) {
  if (value.is_object() && value.contains(key)) return &value[key];
  if (value.is_object() || value.is_array())
    for (const auto& child : value)
      if (const ojson* found = value_of_key(child, key)) return found;
  return nullptr;
}

struct Table {
  std::string title, description;
  std::vector<Row> rows;
};

// The tables of one settings schema: the settings, then one per definition used more than once.
class SchemaDoc {
 public:
  explicit SchemaDoc(const ojson& schema) : root_(object_schema(schema)), defs_(root_.value("$defs", ojson::object())) {
    count_refs(root_);
    Table main;
    main.description = root_.value("description", "");
    collect_rules(root_, "");
    children(root_, "", main.rows);
    tables_.push_back(std::move(main));
    for (std::size_t i = 0; i < shared_.size(); ++i) {  // a table may name further shared definitions
      const std::string shared = shared_[i];            // a copy: walking the definition may grow shared_ (and move its strings)
      const ojson& def = defs_[shared];
      Table table{
          shared + (def.contains("title") ? ": " + def["title"].get<std::string>() : ""), def.value("description", ""), {}};
      const bool record = def.contains("properties") || def.contains("oneOf");
      if (record && type_of(def) == "map") {
        collect_rules(def, shared);
        children(def, "", table.rows, shared);
      } else {  // a value of its own (a line: 17, "GPIO17"), maybe also an object form ({line, active_low})
        add_row(def, def, shared, false, table.rows, shared);
        if (record) children(def, shared, table.rows, shared);
      }
      tables_.push_back(std::move(table));
    }
  }

  const std::vector<Table>& tables() const { return tables_; }
  const std::vector<std::string>& rules() const { return rules_; }
  const ojson& root() const { return root_; }

 private:
  void count_refs(const ojson& node) {
    if (node.is_object()) {
      if (const std::string def = def_name(node); !def.empty()) ++refs_[def];
      for (const auto& [key, value] : node.items())
        if (key != "examples" && key != "default") count_refs(value);
    } else if (node.is_array()) {
      for (const auto& value : node) count_refs(value);
    }
  }

  // A definition used more than once that has settings of its own gets a table; a plain value is shown where used.
  bool shared(const std::string& def) {
    if (def.empty() || refs_[def] < 2 || !defs_.contains(def)) return false;
    if (!defs_[def].contains("properties") && !defs_[def].contains("oneOf")) return false;
    if (std::find(shared_.begin(), shared_.end(), def) == shared_.end()) shared_.push_back(def);
    return true;
  }

  static std::string type_of(const ojson& n) {
    std::vector<std::string> types;
    if (n.contains("type")) {
      if (n["type"].is_string()) types.push_back(n["type"]);
      else
        for (const auto& t : n["type"]) types.push_back(t);
    }
    for (auto& t : types)
      if (t == "array" && n.contains("items") && n["items"].contains("type") && n["items"]["type"].is_string() &&
          n["items"]["type"] != "object")
        t = "list of " + n["items"]["type"].get<std::string>();
      else if (t == "array") t = "list";
      else if (t == "object") t = "map";
    if (types.empty()) return n.contains("oneOf") || n.contains("anyOf") ? "one of the forms below" : "any";
    std::string out;
    for (std::size_t i = 0; i < types.size(); ++i) out += (i == 0 ? "" : i + 1 == types.size() ? " or " : ", ") + types[i];
    return out;
  }

  static std::string range_of(const ojson& n) {
    std::vector<std::string> parts;
    const bool min = n.contains("minimum"), max = n.contains("maximum");
    if (min && max) parts.push_back(text_of(n["minimum"]) + " .. " + text_of(n["maximum"]));
    else if (min) parts.push_back(">= " + text_of(n["minimum"]));
    else if (max) parts.push_back("<= " + text_of(n["maximum"]));
    if (n.contains("exclusiveMinimum")) parts.push_back("> " + text_of(n["exclusiveMinimum"]));
    if (n.contains("exclusiveMaximum")) parts.push_back("< " + text_of(n["exclusiveMaximum"]));
    if (n.contains("enum")) {
      std::vector<std::string> choices;
      for (const auto& c : n["enum"]) choices.push_back(text_of(c));
      parts.push_back("one of " + joined(choices, ", "));
    }
    if (n.contains("const")) parts.push_back("exactly " + text_of(n["const"]));
    if (n.value("minLength", 0) == 1 && !n.contains("maxLength")) parts.push_back("non-empty");
    else if (n.contains("minLength") && n.value("minLength", ojson()) == n.value("maxLength", ojson()))
      parts.push_back(text_of(n["minLength"]) + " characters");
    else if (n.contains("minLength") || n.contains("maxLength"))
      parts.push_back(text_of(n.value("minLength", ojson(0))) + " .. " + text_of(n.value("maxLength", ojson("any"))) +
                      " characters");
    if (n.contains("pattern")) parts.push_back(n.value("errorMessage", "matching " + n["pattern"].get<std::string>()));
    if (n.contains("minItems") || n.contains("maxItems"))
      parts.push_back(n.value("minItems", ojson(0)) == n.value("maxItems", ojson(-1)) ? text_of(n["minItems"]) + " items"
                      : n.contains("maxItems")
                          ? text_of(n.value("minItems", ojson(0))) + " .. " + text_of(n["maxItems"]) + " items"
                          : "at least " + text_of(n["minItems"]) + " item" + (n["minItems"] == 1 ? "" : "s"));
    if (n.contains("minProperties")) parts.push_back("at least " + text_of(n["minProperties"]) + " entries");
    return joined(parts, "; ");
  }

  static std::string claim_of(const ojson& n) {
    const auto claim = n.find("x-claim");
    if (claim == n.end()) return {};
    const std::string resource = claim->value("resource", "");
    std::string what = resource;
    for (const auto& [kind, summary] : sdk::contract::claim_kinds())
      if (kind == resource) what = summary;
    std::vector<std::string> scope;
    for (const auto& s : claim->value("scope", ojson::array())) {
      const std::string pointer = s.is_string() ? s.get<std::string>() : s.value("pointer", "");
      std::string name = pointer.starts_with("/") ? pointer.substr(1) : "its " + pointer;
      if (s.is_object() && s.contains("default")) name += " (default " + text_of(s["default"]) + ")";
      scope.push_back(name);
    }
    return "Claims " + what + (scope.empty() ? "" : ", where: " + joined(scope, ", ")) +
           "; two settings naming the same one are refused.";
  }

  void add_row(const ojson& node, const ojson& n, const std::string& name, bool required, std::vector<Row>& rows,
               const std::string& where) {
    std::string description = node.value("description", n.value("description", ""));
    const std::string claim = claim_of(n).empty() ? claim_of(node) : claim_of(n);
    if (!claim.empty()) description += (description.empty() ? "" : ". ") + claim;
    const ojson fallback = node.contains("default") ? node["default"] : n.value("default", ojson());
    rows.push_back({name, type_of(n), fallback.is_null() ? "" : text_of(fallback), range_of(n), required ? "yes" : "",
                    description, example_of(node, n, name, where)});
    collect_rules(n, name.empty() ? where : name);
  }

  // The setting's own example, else the value it takes in the first of the schema's examples that sets it (in a
  // shared definition's table, `where`: the value its key takes in any example).
  std::string example_of(const ojson& node, const ojson& n, const std::string& name, const std::string& where) const {
    for (const ojson* own : {&node, &n})
      if (own->contains("examples") && (*own)["examples"].is_array() && !(*own)["examples"].empty())
        return (*own)["examples"][0].dump();
    for (const auto& example : root_.value("examples", ojson::array())) {
      const ojson* found = where.empty() ? value_at(example, name) : value_of_key(example, name.substr(name.rfind('.') + 1));
      if (found != nullptr) return found->dump();
    }
    return {};
  }

  void collect_rules(const ojson& n, const std::string& at) {
    const std::string in = at.empty() ? "" : at + ": ";
    for (const auto& rule : n.value("x-rules", ojson::array()))
      rules_.push_back(in + rule.value("rule", "") + " (else: " + rule.value("message", "") + ")");
    for (const auto& [name, needed] : object_at(n, "dependentRequired").items()) {
      std::vector<std::string> list;
      for (const auto& x : needed) list.push_back(x);
      rules_.push_back(in + name + " needs " + joined(list, ", "));
    }
    for (const auto& branch : n.value("allOf", ojson::array()))
      if (branch.contains("then") && branch["then"].contains("errorMessage"))
        rules_.push_back(in + branch["then"]["errorMessage"].get<std::string>());
    if (n.contains("then") && n["then"].contains("errorMessage"))
      rules_.push_back(in + n["then"]["errorMessage"].get<std::string>());
    if (n.contains("not") && n.contains("errorMessage")) rules_.push_back(in + n["errorMessage"].get<std::string>());
  }

  void walk(const ojson& node, const std::string& name, bool required, std::vector<Row>& rows, const std::string& where) {
    const std::string def = def_name(node);
    const ojson& n = !def.empty() && defs_.contains(def) ? defs_[def] : node;
    if (n.contains("not") && n["not"] == ojson::object()) {  // a key that must not be set: a rule, not a setting
      collect_rules(n, name);
      return;
    }
    if (shared(def)) {
      Row row{name, def + " (below)", "", "", required ? "yes" : "", node.value("description", n.value("description", "")), ""};
      if (node.contains("default")) row.fallback = text_of(node["default"]);
      row.example = example_of(node, n, name, where);
      rows.push_back(std::move(row));
      return;
    }
    add_row(node, n, name, required, rows, where);
    children(n, name, rows, where);
  }

  void children(const ojson& n, const std::string& name, std::vector<Row>& rows, const std::string& where = "") {
    const std::string prefix = name.empty() ? "" : name + ".";
    const auto required = required_names(n, defs_);
    for (const auto& [key, property] : object_at(n, "properties").items())
      walk(property, prefix + key, std::find(required.begin(), required.end(), key) != required.end(), rows, where);
    if (n.contains("additionalProperties") && n["additionalProperties"].is_object())
      walk(n["additionalProperties"], prefix + "<name>", false, rows, where);
    for (std::size_t i = 0; i < n.value("prefixItems", ojson::array()).size(); ++i)
      walk(n["prefixItems"][i], name + "[" + std::to_string(i) + "]", true, rows, where);
    if (n.contains("items") &&
        (n["items"].contains("properties") || n["items"].contains("oneOf") || !def_name(n["items"]).empty()))
      children(n["items"], name + "[]", rows, where);
    for (const char* keyword : {"oneOf", "anyOf"})
      for (std::size_t i = 0; i < n.value(keyword, ojson::array()).size(); ++i) {
        const ojson& branch = n[keyword][i];
        if (!branch.contains("properties")) continue;
        const std::string form = (name.empty() ? where : name) + " as " + form_label(branch, i);
        rows.push_back({form, "map", "", "", "", "form " + branch.value("title", form_label(branch, i)), ""});
        collect_rules(branch, form);
        children(branch, name, rows, where);
      }
  }

  ojson root_, defs_;
  std::map<std::string, int> refs_;
  std::vector<std::string> shared_;
  std::vector<Table> tables_;
  std::vector<std::string> rules_;
};

// The YAML a config writes an example in: a drivers[] entry, a runtime.capabilities block, or a top-level block.
std::string example_yaml(const Item& item, const ojson& example, const std::string& block = {}) {
  ojson doc = ojson::object();
  if (!block.empty()) {
    doc[block] = example;
  } else if (item.kind == "driver") {
    ojson entry = ojson::object();
    entry["id"] = example.value("id", item.name + "0");
    entry["protocol"] = item.name;
    for (const auto& [key, value] : example.items())
      if (key != "id" && key != "protocol") entry[key] = value;
    doc["drivers"] = ojson::array({entry});
  } else {
    doc["runtime"]["capabilities"][item.name] = example;
  }
  return yaml::json_to_yaml(doc);
}

std::vector<std::string> item_examples(const Item& item) {
  std::vector<std::string> out;
  for (const auto& example : settings_schema(item).value("examples", ojson::array())) out.push_back(example_yaml(item, example));
  for (const auto& [block, schema] : object_at(item.entry, "reads").items())
    for (const auto& example : schema.value("examples", ojson::array())) out.push_back(example_yaml(item, example, block));
  return out;
}

// "Offers the depth zones (rcand.obstacle_source/1) when camera.depth is set", and what the item needs likewise.
std::vector<std::string> service_lines(const Item& item) {
  std::vector<std::string> out;
  for (const char* key : {"offers", "needs"})
    for (const auto& use : item.entry.value(key, ojson::array())) {
      std::vector<std::string> when = use.value("when", std::vector<std::string>{});
      std::string line =
          std::string(key[0] == 'o' ? "Offers " : "Needs ") + use.value("what", "") + " (" + use.value("service", "") + ")";
      if (!when.empty()) line += " when " + joined(when, " and ") + (when.size() > 1 ? " are" : " is") + " set";
      const std::vector<std::string> any = use.value("when_any", std::vector<std::string>{});
      if (!any.empty()) line += " and one of " + joined(any, ", ");
      if (use.contains("without")) line += "; without it " + use["without"].get<std::string>();
      out.push_back(line + ".");
    }
  return out;
}

std::string where_settings_go(const Item& item) {
  if (item.kind == "driver")
    return "a drivers[] entry with protocol: " + item.name +
           " (id and protocol are the entry's own; every other key must be one of these)";
  return "runtime.capabilities." + item.name;
}

std::string heading(const Item& item) {
  return item.kind + " " + item.name + " (plugin " + item.manifest->document.value("id", "") + " " +
         item.manifest->document.value("version", "") + ")";
}

// ---- text ---------------------------------------------------------------------------------------------------------

std::string wrapped(const std::string& text, std::size_t indent, std::size_t width = 118) {
  std::string out, line;
  std::istringstream words(text);
  std::string word;
  while (words >> word) {
    if (!line.empty() && indent + line.size() + 1 + word.size() > width) {
      out += std::string(indent, ' ') + line + "\n";
      line.clear();
    }
    line += (line.empty() ? "" : " ") + word;
  }
  if (!line.empty()) out += std::string(indent, ' ') + line + "\n";
  return out;
}

std::string text_table(const Table& table) {
  std::string out;
  if (!table.title.empty()) out += "\n  " + table.title + "\n";
  if (!table.description.empty()) out += wrapped(table.description, 2);
  if (table.rows.empty()) return out + "  (no settings)\n";
  std::array<std::size_t, 6> width{7, 4, 7, 7, 5, 8};
  for (const auto& r : table.rows) {
    const std::array<std::size_t, 6> cells{r.name.size(),    r.type.size(),  r.fallback.size(),
                                           r.example.size(), r.range.size(), r.required.size()};
    for (std::size_t i = 0; i < 6; ++i) width[i] = std::max(width[i], std::min<std::size_t>(cells[i], 36));
  }
  auto cell = [](const std::string& text, std::size_t w) {
    return text.size() >= w ? text + " " : text + std::string(w - text.size() + 1, ' ');
  };
  out += "  " + cell("SETTING", width[0]) + cell("TYPE", width[1]) + cell("DEFAULT", width[2]) + cell("EXAMPLE", width[3]) +
         cell("RANGE", width[4]) + "REQUIRED\n";
  for (const auto& r : table.rows) {
    std::string line = "  " + cell(r.name, width[0]) + cell(r.type, width[1]) + cell(r.fallback, width[2]) +
                       cell(r.example, width[3]) + cell(r.range, width[4]) + r.required;
    while (!line.empty() && line.back() == ' ') line.pop_back();
    out += line + "\n";
    if (!r.description.empty()) out += wrapped(r.description, 6);
  }
  return out;
}

std::string item_text(const Item& item) {
  std::string out = heading(item) + "\n";
  out += wrapped(item.manifest->document.value("description", ""), 2);
  if (item.entry.contains("interface")) out += "  Actuator interface: " + item.entry["interface"].get<std::string>() + "\n";
  if (item.entry.contains("fail_safe")) out += wrapped("Fail-safe: " + item.entry["fail_safe"].get<std::string>(), 2);
  const auto requires_ = item.manifest->document.value("requires", ojson::array());
  if (item.kind == "capability" && !requires_.empty())
    out += "  Requires a driver providing: " + joined(requires_.get<std::vector<std::string>>(), ", ") + "\n";
  for (const auto& line : service_lines(item)) out += wrapped(line, 2);
  const SchemaDoc doc(settings_schema(item));
  out += "\nSettings: " + where_settings_go(item) + "\n";
  for (const auto& table : doc.tables()) out += text_table(table);
  if (!doc.rules().empty()) {
    out += "\n  Rules:\n";
    for (const auto& rule : doc.rules()) out += wrapped("- " + rule, 4);
  }
  for (const auto& [block, schema] : object_at(item.entry, "reads").items()) {
    const SchemaDoc read(schema);
    out += "\nReads the top-level config block `" + block + "`:\n";
    for (const auto& table : read.tables()) out += text_table(table);
    if (!read.rules().empty()) {
      out += "\n  Rules:\n";
      for (const auto& rule : read.rules()) out += wrapped("- " + rule, 4);
    }
  }
  const auto examples = item_examples(item);
  for (std::size_t i = 0; i < examples.size(); ++i) {
    out += "\nExample " + std::to_string(i + 1) + " (passes rcand --check-config):\n";
    std::istringstream lines(examples[i]);
    for (std::string line; std::getline(lines, line);) out += "    " + line + "\n";
  }
  return out;
}

// ---- markdown -----------------------------------------------------------------------------------------------------

std::string md_cell(std::string text) {
  std::string out;
  for (const char c : text) out += c == '|' ? std::string("\\|") : std::string(1, c);
  return out;
}

std::string md_table(const Table& table) {
  std::string out;
  if (!table.title.empty()) out += "\n**" + md_cell(table.title) + "**\n";
  if (!table.description.empty()) out += "\n" + table.description + "\n";
  if (table.rows.empty()) return out + "\nNo settings.\n";
  out += "\n| Setting | Type | Default | Example | Range | Required | Description |\n|---|---|---|---|---|---|---|\n";
  const auto code = [](const std::string& text) { return text.empty() ? std::string() : "`" + md_cell(text) + "`"; };
  for (const auto& r : table.rows)
    out += "| `" + md_cell(r.name) + "` | " + md_cell(r.type) + " | " + code(r.fallback) + " | " + code(r.example) + " | " +
           md_cell(r.range) + " | " + r.required + " | " + md_cell(r.description) + " |\n";
  return out;
}

// GitHub's anchor for the section heading "<kind> `<name>`": lower case, punctuation other than - and _ dropped.
std::string anchor(const Item& item) {
  std::string out;
  for (const char c : item.kind + " " + item.name) {
    if (c == ' ') out += '-';
    else if (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_')
      out += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  return out;
}

// `same_as`: the heading of an earlier section with the very same settings (an alias of the same plugin), or "".
std::string item_markdown(const Item& item, const std::string& same_as = {}) {
  std::string out = "\n## " + item.kind + " `" + item.name + "`\n\n";
  out += "Plugin `" + item.manifest->document.value("id", "") + "` " + item.manifest->document.value("version", "") + ". " +
         item.manifest->document.value("description", "") + "\n";
  if (item.entry.contains("interface")) out += "\nActuator interface: `" + item.entry["interface"].get<std::string>() + "`.\n";
  if (item.entry.contains("fail_safe")) out += "\nFail-safe: " + item.entry["fail_safe"].get<std::string>() + "\n";
  const auto requires_ = item.manifest->document.value("requires", ojson::array());
  if (item.kind == "capability" && !requires_.empty())
    out += "\nRequires a driver providing: `" + joined(requires_.get<std::vector<std::string>>(), "`, `") + "`.\n";
  for (const auto& line : service_lines(item)) out += "\n" + line + "\n";
  if (!same_as.empty()) return out + "\nSettings and examples: as " + same_as + ", with `protocol: " + item.name + "`.\n";
  const SchemaDoc doc(settings_schema(item));
  out += "\n### Settings\n\nWhere: " + where_settings_go(item) + ".\n";
  for (const auto& table : doc.tables()) out += md_table(table);
  if (!doc.rules().empty()) {
    out += "\nRules:\n\n";
    for (const auto& rule : doc.rules()) out += "- " + rule + "\n";
  }
  for (const auto& [block, schema] : object_at(item.entry, "reads").items()) {
    const SchemaDoc read(schema);
    out += "\n### The `" + block + "` block\n";
    for (const auto& table : read.tables()) out += md_table(table);
    if (!read.rules().empty()) {
      out += "\nRules:\n\n";
      for (const auto& rule : read.rules()) out += "- " + rule + "\n";
    }
  }
  const auto examples = item_examples(item);
  if (!examples.empty()) out += "\n### Example" + std::string(examples.size() > 1 ? "s" : "") + "\n";
  for (const auto& example : examples) out += "\n```yaml\n" + example + "```\n";
  return out;
}

}  // namespace

std::optional<std::string> describe_text(const std::vector<ManifestText>& manifests, const std::string& id) {
  const auto items = items_named(manifests, id);
  if (items.empty() || id.empty()) return std::nullopt;
  std::string out;
  for (std::size_t i = 0; i < items.size(); ++i) out += (i ? "\n\n" : "") + item_text(items[i]);
  return out;
}

std::optional<std::string> describe_markdown(const std::vector<ManifestText>& manifests, const std::string& id) {
  const auto items = items_named(manifests, id);
  if (items.empty()) return std::nullopt;
  std::string out;
  if (id.empty()) {
    out =
        "# Drivers and capabilities: settings reference\n\n"
        "Generated from the plugin manifests by `rcand --describe --markdown` (the drivers_doc test, tests/drivers_doc.cmake, "
        "keeps this "
        "file equal to it): do not edit it by hand. Each section lists the settings of a `drivers:` entry or a "
        "`runtime.capabilities.<name>` block, with every example checked by `rcand --check-config`. "
        "`rcand --describe NAME` prints the same for one driver protocol, capability or plugin. How the settings "
        "are checked: docs/protocol.md §10.\n\n";
    for (const auto& item : items) out += "- [" + item.kind + " `" + item.name + "`](#" + anchor(item) + ")\n";
  }
  std::map<std::string, std::string> sections;  // plugin id + kind + settings schema -> the first section's link
  for (const auto& item : items) {
    const std::string key = item.manifest->document.value("id", "") + "\n" + item.kind + "\n" + settings_schema(item).dump() +
                            object_at(item.entry, "reads").dump();
    const auto [first, fresh] = sections.emplace(key, "[" + item.kind + " `" + item.name + "`](#" + anchor(item) + ")");
    out += item_markdown(item, fresh || !id.empty() ? std::string() : first->second);
  }
  return out;
}

std::vector<std::string> describable(const std::vector<ManifestText>& manifests) {
  std::set<std::string> names;
  for (const auto& item : all_items(manifests)) {
    names.insert(item.name);
    names.insert(item.manifest->document.value("id", ""));
  }
  return {names.begin(), names.end()};
}

std::vector<std::string> example_blocks(const std::vector<ManifestText>& manifests, const std::string& id) {
  std::vector<std::string> out;
  for (const auto& item : items_named(manifests, id))
    for (auto& example : item_examples(item)) out.push_back(std::move(example));
  return out;
}

}  // namespace rcand::plugin_docs
