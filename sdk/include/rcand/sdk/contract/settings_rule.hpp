// A settings schema's "x-rules": a condition on several settings of one object that JSON Schema cannot say
// ("min_us < neutral_us && neutral_us < max_us", "watchdog_ms == 0 || watchdog_ms * poll_hz >= 2000"). The grammar
// is deliberately small: numbers, true/false, the object's own settings by name, + - * /, comparisons, ! && || and
// parentheses. A rule naming a setting that is not set (after defaults) does not apply. Pure and header-only; part of
// the settings contract (settings.hpp).
#pragma once

#include <nlohmann/json.hpp>

#include <cctype>
#include <cmath>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>

namespace rcand::sdk::contract {

// A rule that does not parse ("min_us < < max_us"): the manifest is refused with this message.
class RuleSyntaxError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class SettingsRule {
 public:
  // Parses `text`; throws RuleSyntaxError.
  explicit SettingsRule(std::string_view text) : text_(text) {
    Parser parser{text_, 0, names_};
    parser.check_only();
  }

  // The settings the rule names, for the manifest check (each must be a property of the object).
  const std::set<std::string>& names() const noexcept { return names_; }

  // True or false for `object`; nullopt when a setting it names is absent, null or not a number/boolean (the type
  // check reports that), so the rule does not apply.
  std::optional<bool> holds(const nlohmann::json& object) const {
    for (const auto& name : names_) {
      const auto it = object.find(name);
      if (it == object.end() || !(it->is_number() || it->is_boolean())) return std::nullopt;
    }
    std::set<std::string> unused;
    Parser parser{text_, 0, unused, &object};
    const Value value = parser.expression();
    return truthy(value);
  }

 private:
  using Value = std::variant<double, bool>;

  static bool truthy(const Value& v) { return std::holds_alternative<bool>(v) ? std::get<bool>(v) : std::get<double>(v) != 0.0; }
  static double number(const Value& v) {
    return std::holds_alternative<double>(v) ? std::get<double>(v) : (std::get<bool>(v) ? 1.0 : 0.0);
  }

  // Recursive descent over the text; with `object` null it only checks the syntax and collects the names.
  struct Parser {
    std::string_view text;
    std::size_t at;
    std::set<std::string>& names;
    const nlohmann::json* object = nullptr;

    void check_only() {
      expression();
      skip();
      if (at != text.size()) fail("unexpected '" + std::string(text.substr(at, 1)) + "'");
    }
    [[noreturn]] void fail(const std::string& what) const {
      throw RuleSyntaxError("rule \"" + std::string(text) + "\": " + what + " at character " + std::to_string(at + 1));
    }
    void skip() {
      while (at < text.size() && std::isspace(static_cast<unsigned char>(text[at]))) ++at;
    }
    bool take(std::string_view token) {
      skip();
      if (text.substr(at, token.size()) != token) return false;
      // "<" must not swallow the first character of "<=", nor "!" that of "!=".
      if (token.size() == 1 && at + 1 < text.size() && text[at + 1] == '=' &&
          std::string_view("<>!=").find(token[0]) != std::string_view::npos)
        return false;
      at += token.size();
      return true;
    }
    Value expression() {
      Value left = conjunction();
      while (take("||")) {
        const Value right = conjunction();
        left = truthy(left) || truthy(right);
      }
      return left;
    }
    Value conjunction() {
      Value left = negation();
      while (take("&&")) {
        const Value right = negation();
        left = truthy(left) && truthy(right);
      }
      return left;
    }
    Value negation() {
      if (take("!")) return !truthy(negation());
      return comparison();
    }
    Value comparison() {
      const Value left = sum();
      for (const std::string_view op : {"<=", ">=", "==", "!=", "<", ">"}) {
        if (!take(op)) continue;
        const double a = number(left), b = number(sum());
        if (op == "<=") return a <= b;
        if (op == ">=") return a >= b;
        if (op == "==") return a == b;
        if (op == "!=") return a != b;
        if (op == "<") return a < b;
        return a > b;
      }
      return left;
    }
    Value sum() {
      const Value first = product();
      double value = number(first);
      bool combined = false;
      for (;;) {
        if (take("+")) value += number(product());
        else if (take("-")) value -= number(product());
        else return combined ? Value(value) : first;
        combined = true;
      }
    }
    Value product() {
      const Value first = unary();
      double value = number(first);
      bool combined = false;
      for (;;) {
        if (take("*")) value *= number(unary());
        else if (take("/")) {
          const double divisor = number(unary());
          value = divisor == 0.0 ? std::nan("") : value / divisor;
        } else return combined ? Value(value) : first;
        combined = true;
      }
    }
    Value unary() {
      if (take("-")) return -number(unary());
      return primary();
    }
    Value primary() {
      skip();
      if (take("(")) {
        const Value inner = expression();
        if (!take(")")) fail("expected ')'");
        return inner;
      }
      if (at < text.size() && (std::isdigit(static_cast<unsigned char>(text[at])) || text[at] == '.')) {
        const std::size_t start = at;
        while (at < text.size() && (std::isalnum(static_cast<unsigned char>(text[at])) || text[at] == '.')) ++at;
        try {
          std::size_t used = 0;
          const std::string literal(text.substr(start, at - start));
          const double value = std::stod(literal, &used);
          if (used != literal.size()) fail("bad number '" + literal + "'");
          return value;
        } catch (const std::logic_error&) {
          fail("bad number");
        }
      }
      if (at < text.size() && (std::isalpha(static_cast<unsigned char>(text[at])) || text[at] == '_')) {
        const std::size_t start = at;
        while (at < text.size() && (std::isalnum(static_cast<unsigned char>(text[at])) || text[at] == '_')) ++at;
        const std::string name(text.substr(start, at - start));
        if (name == "true" || name == "false") return name == "true";
        if (object == nullptr) {
          names.insert(name);
          return 0.0;
        }
        const auto& value = object->at(name);
        return value.is_boolean() ? Value(value.get<bool>()) : Value(value.get<double>());
      }
      fail(at < text.size() ? "unexpected '" + std::string(text.substr(at, 1)) + "'" : "unexpected end");
    }
  };

  std::string text_;
  std::set<std::string> names_;
};

}  // namespace rcand::sdk::contract
