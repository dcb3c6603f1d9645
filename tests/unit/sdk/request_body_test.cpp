// rcand/sdk/request_body.hpp: every reader refuses a value of another type with a 400 naming the field - never a
// json::type_error - and quotes a client's value only bounded.
#include <doctest/doctest.h>

#include <rcand/sdk/request_body.hpp>

#include <string>
#include <vector>

using rcand::sdk::BodyReader;
using rcand::sdk::Field;
using rcand::sdk::Json;

namespace {

// Values of every JSON type, huge ones included.
std::vector<Json> confused_values() {
  return {nullptr,
          true,
          0,
          -1,
          1.5,
          1e308,
          18446744073709551615ull,
          "",
          "x",
          std::string(200000, 'a'),
          Json::array(),
          Json::array({1, "a"}),
          Json::object(),
          Json{{"a", 1}}};
}

void check_refusal(const BodyReader& in, const std::string& field) {
  REQUIRE(in.error());
  CHECK(in.error()->status == 400);
  CHECK(in.error()->body["code"] == "BAD_REQUEST");
  CHECK(in.error()->body["field"] == field);
  CHECK(in.error()->body["error"].get<std::string>().size() < 300);  // a 200 KB value is never quoted whole
}

}  // namespace

TEST_CASE("BodyReader: a body that is not an object is refused naming \"body\"") {
  for (const auto& body : confused_values()) {
    if (body.is_object()) continue;
    BodyReader in(body);
    check_refusal(in, "body");
    CHECK_FALSE(in.string("a", Field::Required));  // later readers only return nothing
    CHECK(in.error()->body["field"] == "body");
  }
}

TEST_CASE("BodyReader: every reader refuses every other type with a 400 naming the field, and never throws") {
  for (const auto& value : confused_values()) {
    CAPTURE(value.dump().substr(0, 40));
    const Json body{{"f", value}};
    if (!value.is_null() && !value.is_string()) {
      BodyReader in(body);
      CHECK_NOTHROW(in.string("f"));
      check_refusal(in, "f");
    }
    if (!value.is_null() && !(value.is_string() && value == "x")) {
      BodyReader in(body);
      CHECK_NOTHROW(in.one_of("f", {"x", "y"}));
      check_refusal(in, "f");
      CHECK(in.error()->body["allowed"] == Json::array({"x", "y"}));
    }
    if (!value.is_null() && !(value.is_number() && value.get<double>() >= -10 && value.get<double>() <= 10)) {
      BodyReader in(body);
      CHECK_NOTHROW(in.number("f", -10, 10));
      check_refusal(in, "f");
    }
    if (!value.is_null() && !(value.is_number_integer() && value.get<double>() >= -1 && value.get<double>() <= 100)) {
      BodyReader in(body);
      CHECK_NOTHROW(in.integer("f", -1, 100));
      check_refusal(in, "f");
    }
    if (!value.is_null() && !value.is_boolean()) {
      BodyReader in(body);
      CHECK_NOTHROW(in.boolean("f"));
      check_refusal(in, "f");
    }
    if (!value.is_null() && !value.is_object()) {
      BodyReader in(body);
      CHECK(in.object("f") == nullptr);
      check_refusal(in, "f");
    }
  }
}

TEST_CASE("BodyReader: good values are read; absent and null are the same; the first fault wins") {
  const Json body{{"s", "hello"}, {"d", "deny"},     {"n", 0.5},    {"i", 7},
                  {"b", false},   {"o", {{"k", 1}}}, {"a", {1, 2}}, {"z", nullptr}};
  BodyReader in(body);
  CHECK(in.string("s", Field::Required, 5) == "hello");
  CHECK(in.one_of("d", {"approve", "deny"}, Field::Required) == "deny");
  CHECK(in.number("n", 0, 1) == 0.5);
  CHECK(in.integer("i", 1, 10) == 7);
  CHECK(in.boolean("b") == false);
  CHECK(in.object("o") != nullptr);
  CHECK(in.array("a", 2) != nullptr);
  CHECK_FALSE(in.string("z"));        // null: absent
  CHECK_FALSE(in.string("missing"));  // optional
  CHECK(in.ok());

  CHECK_FALSE(in.string("s", Field::Required, 4));  // one byte too long
  CHECK(in.error()->body["field"] == "s");
  CHECK_FALSE(in.string("missing", Field::Required));
  CHECK(in.error()->body["field"] == "s");  // still the first fault

  const Json empty = Json::object();
  BodyReader required(empty);
  CHECK_FALSE(required.integer("count", 0, 5, Field::Required));
  CHECK(required.error()->body["error"] == "count is required: an integer in [0, 5]");
  const Json three{{"a", {1, 2, 3}}};
  BodyReader many(three);
  CHECK(many.array("a", 2) == nullptr);
  CHECK(many.error()->body["field"] == "a");
}

TEST_CASE("bounded_utf8 cuts at a character boundary; describe_value never quotes a long value whole") {
  const std::string text =
      "ab\xC3\xA9"
      "cd";  // "abécd": é is two bytes
  CHECK(rcand::sdk::bounded_utf8(text, 10) == text);
  CHECK(rcand::sdk::bounded_utf8(text, 3) == "ab...");  // not half of é
  CHECK(rcand::sdk::bounded_utf8(text, 4) == "ab\xC3\xA9...");
  CHECK(rcand::sdk::describe_value(Json(std::string(100000, 'x'))) == "a string of 100000 bytes");
  CHECK(rcand::sdk::describe_value(Json(5)) == "5");
  CHECK(rcand::sdk::describe_value(Json::array({std::string(100, 'x')})) == "an array of 1 items");
}
