// Every JSON answer rcand builds, and the one error body (docs/protocol.md §4): {"error","code","status"} plus
// extras such as "field", built by the SDK's sdk::Response::error so kernel, services and the SDK's fake host can
// never disagree on its shape.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <string_view>

#include "libs/http/response.hpp"

namespace rcand::kernel {

http::Response json_response(int status, const nlohmann::json& body);
http::Response error_response(int status, std::string_view code, std::string message,
                              nlohmann::json extra = nlohmann::json::object());

}  // namespace rcand::kernel
