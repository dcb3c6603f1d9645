// Requests and responses as capabilities see them: already authenticated, body already parsed as JSON.
#pragma once

#include <nlohmann/json.hpp>

#include <map>
#include <string>
#include <utility>

#include "rcand/sdk/scope.hpp"

namespace rcand::sdk {

using Json = nlohmann::json;

struct Request {
  std::string method;                        // "GET", "POST", ...
  std::string path;                          // full target path without the query, e.g. "/api/action"
  std::string subpath;                       // for custom capabilities: what follows "/api/cap/<name>"
  std::map<std::string, std::string> query;  // decoded query parameters
  Json body;                                 // parsed JSON body; null when the request had none
  std::string principal;                     // who is asking (token principal or JWT "sub")
  Role role = Role::Guest;                   // the caller's role
  std::string message_id;                    // the id this request carries in the audit log
};

struct Response {
  int status = 200;
  Json body = Json::object();

  static Response ok(Json body = Json::object()) { return {200, std::move(body)}; }

  // The error body every non-2xx answer carries (docs/protocol.md §4): {"error","code","status"} plus extras.
  static Response error(int status, std::string code, std::string message, Json extra = Json::object()) {
    Json body = std::move(extra);
    body["error"] = std::move(message);
    body["code"] = std::move(code);
    body["status"] = status;
    return {status, std::move(body)};
  }

  // 400 naming the field at fault.
  static Response bad_request(std::string field, std::string message) {
    return error(400, "BAD_REQUEST", std::move(message), Json{{"field", std::move(field)}});
  }
};

}  // namespace rcand::sdk
