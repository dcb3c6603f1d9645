// A typed, read-only view of a JSON configuration subtree (the kernel converts YAML to JSON).
#pragma once

#include <nlohmann/json.hpp>

#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace rcand::sdk {

class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Immutable after construction: any thread, never blocks.
class ConfigView {
 public:
  ConfigView() = default;
  explicit ConfigView(nlohmann::json root) : root_(std::move(root)) {}

  // `path` is dot separated: "physics.wheel_circumference_m".
  bool has(std::string_view path) const { return find(path) != nullptr; }

  // The value at `path` converted to T, or nullopt when absent or null. Throws ConfigError naming the path
  // when present with another type.
  template <class T> std::optional<T> get(std::string_view path) const {
    const nlohmann::json* node = find(path);
    if (node == nullptr || node->is_null()) return std::nullopt;
    if (!matches<T>(*node))
      throw ConfigError(std::string(path) + ": expected " + type_name<T>() + ", found " + node->type_name());
    return node->get<T>();
  }
  template <class T> T get_or(std::string_view path, T fallback) const { return get<T>(path).value_or(std::move(fallback)); }

  // A view of a subtree (empty when absent).
  ConfigView sub(std::string_view path) const {
    const nlohmann::json* node = find(path);
    return node ? ConfigView(*node) : ConfigView();
  }
  const nlohmann::json& raw() const noexcept { return root_; }

 private:
  const nlohmann::json* find(std::string_view path) const {
    const nlohmann::json* node = &root_;
    while (!path.empty()) {
      const auto dot = path.find('.');
      const std::string key(path.substr(0, dot));
      if (!node->is_object()) return nullptr;
      const auto it = node->find(key);
      if (it == node->end()) return nullptr;
      node = &*it;
      path = dot == std::string_view::npos ? std::string_view{} : path.substr(dot + 1);
    }
    return node;
  }
  template <class T> static bool matches(const nlohmann::json& j) {
    if constexpr (std::is_same_v<T, bool>) return j.is_boolean();
    else if constexpr (std::is_integral_v<T>) return j.is_number_integer();
    else if constexpr (std::is_floating_point_v<T>) return j.is_number();
    else if constexpr (std::is_same_v<T, std::string>) return j.is_string();
    else return true;
  }
  template <class T> static const char* type_name() {
    if constexpr (std::is_same_v<T, bool>) return "boolean";
    else if constexpr (std::is_integral_v<T>) return "integer";
    else if constexpr (std::is_floating_point_v<T>) return "number";
    else if constexpr (std::is_same_v<T, std::string>) return "string";
    else return "value";
  }

  nlohmann::json root_ = nlohmann::json::object();
};

}  // namespace rcand::sdk
