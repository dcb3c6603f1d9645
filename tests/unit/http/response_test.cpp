#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include "libs/http/request.hpp"
#include "libs/http/response.hpp"

namespace http = rcand::http;

TEST_CASE("error_response has exactly the §4 shape") {
  auto response = http::error_response(413, "PAYLOAD_TOO_LARGE", "request body exceeds the limit");
  CHECK(response.status == 413);
  CHECK(response.content_type == "application/json");
  auto body = nlohmann::json::parse(response.body);
  CHECK(body == nlohmann::json{{"error", "request body exceeds the limit"}, {"code", "PAYLOAD_TOO_LARGE"},
                               {"status", 413}});
  CHECK(body["status"].is_number_integer());
}

TEST_CASE("error_response survives invalid UTF-8 in the message") {
  auto response = http::error_response(400, "BAD_REQUEST", "bad byte \xff here");
  auto body = nlohmann::json::parse(response.body);
  CHECK(body["code"] == "BAD_REQUEST");
  CHECK(body["error"].get<std::string>().find("bad byte") == 0);
}

TEST_CASE("Request::header looks up lower-case names") {
  http::Request request;
  request.headers = {{"content-type", "text/plain"}};
  CHECK(request.header("content-type") == "text/plain");
  CHECK_FALSE(request.header("accept").has_value());
}
