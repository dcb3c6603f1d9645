#include "kernel/api/answers.hpp"

#include <rcand/sdk/http.hpp>

namespace rcand::kernel {

http::Response json_response(int status, const nlohmann::json& body) {
  http::Response response;
  response.status = status;
  // Invalid UTF-8 from a plugin or a peer is replaced, never a reason to fail the answer.
  response.body = body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  return response;
}

http::Response error_response(int status, std::string_view code, std::string message, nlohmann::json extra) {
  return json_response(status, sdk::Response::error(status, std::string(code), std::move(message), std::move(extra)).body);
}

}  // namespace rcand::kernel
