// Requests and responses as capabilities see them: already authenticated, body already parsed as JSON.
#pragma once

#include <nlohmann/json.hpp>

#include <algorithm>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "rcand/sdk/export.hpp"
#include "rcand/sdk/scope.hpp"

namespace rcand::sdk {

using Json = nlohmann::json;

// The credential a caller authenticated with, as the host keeps it (ABI 1.3). Opaque to plugins: copy the pointer
// along and hand it back with a RequestDispatcher::dispatch; rcand then authorizes the caller again at that moment
// with what the credential is worth then (a token removed by a config reload, a JWT past its exp, a role lowered: the
// dispatched request is refused as that caller's own HTTP request would be). Never holds anything a plugin may read.
class RCAND_INTERFACE Credential {
 public:
  virtual ~Credential() = default;
};

struct Request {
  std::string method;                        // "GET", "POST", ...
  std::string path;                          // full target path without the query, e.g. "/api/action"
  std::string subpath;                       // for custom capabilities: what follows "/api/cap/<name>"
  std::map<std::string, std::string> query;  // decoded query parameters
  Json body;                                 // parsed JSON body; null when the request had none
  std::string principal;                     // who is asking (token principal or JWT "sub")
  Role role = Role::Guest;                   // the caller's role
  std::string message_id;                    // the id this request carries in the audit log
  // ABI 1.3, appended (a plugin built for 1.2 never reads them): what the caller's credential grants - its role's
  // default scopes, narrowed by a JWT's `scope` claim. Decide what to show or do beyond the route's own scope by
  // these (has_scope), never by `role`: an OWNER JWT narrowed to status and control has no `config`.
  std::vector<Scope> scopes;
  // ABI 1.3: the caller's credential (see Credential), for acting on the caller's behalf later; null when the
  // request came from something rcand authenticated otherwise (an R2R peer).
  std::shared_ptr<const Credential> credential;

  bool has_scope(Scope scope) const noexcept {
    return scope == Scope::None || std::find(scopes.begin(), scopes.end(), scope) != scopes.end();
  }
};

// Every scope `role` grants by default (docs/protocol.md §2), in table order: what Request::scopes holds for a
// credential that does not narrow its role (a pre-shared token).
inline std::vector<Scope> default_scopes_of(Role role) {
  std::vector<Scope> scopes;
  for (Scope s : {Scope::Status, Scope::Control, Scope::Config, Scope::Training, Scope::Admin})
    if (role_grants(role, s)) scopes.push_back(s);
  return scopes;
}

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
