#include "libs/http/response.hpp"

#include <nlohmann/json.hpp>

namespace rcand::http {

Response error_response(int status, std::string_view code, std::string_view message) {
  nlohmann::json body = {{"error", message}, {"code", code}, {"status", status}};
  Response response;
  response.status = status;
  // Messages may quote client input; replacing bad UTF-8 keeps an error path from throwing.
  response.body = body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  return response;
}

}  // namespace rcand::http
