#include "libs/base/json_body.hpp"

namespace rcand {
namespace {
struct TooDeep {};
}  // namespace

JsonBody parse_json_body(std::string_view text) {
  JsonBody result;
  if (text.find_first_not_of(" \t\r\n") == std::string_view::npos) return result;
  try {
    result.value = nlohmann::json::parse(text, [](int depth, nlohmann::json::parse_event_t, nlohmann::json&) {
      if (depth > kMaxJsonDepth) throw TooDeep{};
      return true;
    });
  } catch (const TooDeep&) {
    result.error = "body nests deeper than " + std::to_string(kMaxJsonDepth) + " levels";
  } catch (const nlohmann::json::parse_error& e) {
    // Our words, not the library's: its message quotes the input back ("last read: ...") and names its internals.
    result.error = "body is not valid JSON (syntax error at byte " + std::to_string(e.byte) + ")";
  } catch (const nlohmann::json::exception&) {
    result.error = "body is not valid JSON";
  }
  return result;
}

}  // namespace rcand
