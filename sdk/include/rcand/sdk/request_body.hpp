// Reading a request's JSON body field by field. Each reader checks the field's type and bounds before it touches the
// value, and the first fault becomes a 400 BAD_REQUEST naming the field (docs/protocol.md §4), so a handler never
// calls get<T>() or value() on what a client sent: nlohmann::json throws json::type_error for a value of another type
// (a number where a string was expected), and an exception out of a handler is a 500 and a bug, never the answer to a
// bad request.
//
//   sdk::BodyReader in(request.body);
//   const auto id = in.string("thought_id", sdk::Field::Required, 64);
//   const auto decision = in.one_of("decision", {"approve", "deny"}, sdk::Field::Required);
//   const auto reason = in.string("reason", sdk::Field::Optional, 500);
//   if (in.error()) return *in.error();      // 400 {"error", "code", "status", "field"}
//
// Absent and null are the same (an optional field left out); a required one then answers "<field> is required".
// Every value quoted back in an error is bounded (describe_value): a client's megabyte string is never echoed. Header-
// only; any thread (one reader per request).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>

#include "rcand/sdk/http.hpp"

namespace rcand::sdk {

enum class Field { Optional, Required };

// `text` cut to at most `max_bytes` at a UTF-8 character boundary (an invalid byte counts as one character), with
// "..." appended when it was cut. For quoting untrusted text back: in an answer, a log line, a stored record.
inline std::string bounded_utf8(std::string_view text, std::size_t max_bytes) {
  if (text.size() <= max_bytes) return std::string(text);
  std::size_t end = max_bytes;
  while (end > 0 && (static_cast<unsigned char>(text[end]) & 0xC0) == 0x80) --end;  // not inside a character
  return std::string(text.substr(0, end)) + "...";
}

// A client's value as an error message may quote it: its JSON text when short, else its type and size.
inline std::string describe_value(const Json& value, std::size_t max_bytes = 64) {
  const std::string text = value.dump(-1, ' ', false, Json::error_handler_t::replace);
  if (text.size() <= max_bytes) return text;
  if (value.is_string()) return "a string of " + std::to_string(value.get_ref<const std::string&>().size()) + " bytes";
  if (value.is_structured()) return std::string("an ") + value.type_name() + " of " + std::to_string(value.size()) + " items";
  return bounded_utf8(text, max_bytes);
}

class BodyReader {
 public:
  // `body` must outlive the reader. A body that is not an object is the first fault ("body").
  // A temporary would be gone before the first read: the reader keeps a reference.
  BodyReader(Json&&, std::string_view = {}) = delete;
  explicit BodyReader(const Json& body, std::string_view expected = "a JSON object") : body_(body) {
    if (!body_.is_object())
      fail("body", "the body must be " + std::string(expected) + ", found " + (body_.is_null() ? "none" : body_.type_name()));
  }

  // The first fault, as the 400 to answer; nullopt while every field read so far was right.
  const std::optional<Response>& error() const noexcept { return error_; }
  bool ok() const noexcept { return !error_; }

  // The field as it is (any type), or null when absent; nullptr once a fault was found.
  const Json* raw(std::string_view field, Field need = Field::Optional) { return find(field, need, "a value"); }

  // A string of at most `max_bytes` bytes (non-empty when `non_empty`).
  std::optional<std::string> string(std::string_view field, Field need = Field::Optional, std::size_t max_bytes = 4096,
                                    bool non_empty = false) {
    const Json* v = find(field, need, "a string");
    if (v == nullptr) return std::nullopt;
    if (!v->is_string()) {
      wrong(field, "a string", *v);
      return std::nullopt;
    }
    const auto& text = v->get_ref<const std::string&>();
    if (text.size() > max_bytes)
      fail(field,
           std::string(field) + " must be at most " + std::to_string(max_bytes) + " bytes, found " + std::to_string(text.size()));
    else if (non_empty && text.empty()) fail(field, std::string(field) + " must not be empty");
    if (error_) return std::nullopt;
    return text;
  }

  // One of `allowed` (exactly, case-sensitive); the 400 lists them as "allowed".
  std::optional<std::string> one_of(std::string_view field, std::initializer_list<std::string_view> allowed,
                                    Field need = Field::Optional) {
    std::string list;
    Json names = Json::array();
    for (auto name : allowed) {
      list += (list.empty() ? "\"" : ", \"") + std::string(name) + "\"";
      names.push_back(name);
    }
    const Json* v = find(field, need, list);
    if (v == nullptr) return std::nullopt;
    if (v->is_string())
      for (auto name : allowed)
        if (v->get_ref<const std::string&>() == name) return std::string(name);
    error_ = Response::error(400, "BAD_REQUEST", std::string(field) + " must be one of " + list + ", found " + describe_value(*v),
                             Json{{"field", std::string(field)}, {"allowed", std::move(names)}});
    return std::nullopt;
  }

  // A finite number in [min, max].
  std::optional<double> number(std::string_view field, double min, double max, Field need = Field::Optional) {
    const std::string expected = "a number in [" + shortest(min) + ", " + shortest(max) + "]";
    const Json* v = find(field, need, expected);
    if (v == nullptr) return std::nullopt;
    const double x = v->is_number() ? v->get<double>() : NAN;
    if (!std::isfinite(x) || x < min || x > max) {
      wrong(field, expected, *v);
      return std::nullopt;
    }
    return x;
  }

  // An integer in [min, max] (a number with a fraction is not one; compared as a double first, so a huge unsigned
  // value never wraps around).
  std::optional<std::int64_t> integer(std::string_view field, std::int64_t min, std::int64_t max, Field need = Field::Optional) {
    const std::string expected = "an integer in [" + std::to_string(min) + ", " + std::to_string(max) + "]";
    const Json* v = find(field, need, expected);
    if (v == nullptr) return std::nullopt;
    if (!v->is_number_integer() || v->get<double>() < static_cast<double>(min) || v->get<double>() > static_cast<double>(max)) {
      wrong(field, expected, *v);
      return std::nullopt;
    }
    return v->is_number_unsigned() ? static_cast<std::int64_t>(v->get<std::uint64_t>()) : v->get<std::int64_t>();
  }

  std::optional<bool> boolean(std::string_view field, Field need = Field::Optional) {
    const Json* v = find(field, need, "true or false");
    if (v == nullptr) return std::nullopt;
    if (!v->is_boolean()) {
      wrong(field, "true or false", *v);
      return std::nullopt;
    }
    return v->get<bool>();
  }

  // An object or an array, to be read further (by another BodyReader, or element by element).
  const Json* object(std::string_view field, Field need = Field::Optional) {
    const Json* v = find(field, need, "an object");
    if (v == nullptr || v->is_object()) return v;
    wrong(field, "an object", *v);
    return nullptr;
  }
  const Json* array(std::string_view field, std::size_t max_items, Field need = Field::Optional) {
    const Json* v = find(field, need, "a list");
    if (v == nullptr) return nullptr;
    if (!v->is_array()) wrong(field, "a list", *v);
    else if (v->size() > max_items)
      fail(field, std::string(field) + " must have at most " + std::to_string(max_items) + " items");
    return error_ ? nullptr : v;
  }

 private:
  static std::string shortest(double x) {
    std::string text = Json(x).dump();
    if (text.size() > 2 && text.ends_with(".0")) text.resize(text.size() - 2);
    return text;
  }
  // The field's value, or nullptr: absent or null (a fault when required), or a fault found before.
  const Json* find(std::string_view field, Field need, const std::string& expected) {
    if (error_) return nullptr;
    const auto it = body_.find(std::string(field));
    if (it != body_.end() && !it->is_null()) return &*it;
    if (need == Field::Required) fail(field, std::string(field) + " is required: " + expected);
    return nullptr;
  }
  void wrong(std::string_view field, const std::string& expected, const Json& found) {
    fail(field, std::string(field) + " must be " + expected + ", found " + describe_value(found));
  }
  // Records the first fault only.
  void fail(std::string_view field, std::string message) {
    if (!error_) error_ = Response::bad_request(std::string(field), std::move(message));
  }

  const Json& body_;
  std::optional<Response> error_;
};

}  // namespace rcand::sdk
