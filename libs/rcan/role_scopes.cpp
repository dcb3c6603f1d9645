#include "libs/rcan/role_scopes.hpp"

#include "rcand/sdk/http.hpp"

namespace rcand {

std::vector<sdk::Scope> default_scopes(sdk::Role role) { return sdk::default_scopes_of(role); }

std::vector<sdk::Scope> granted_scopes(sdk::Role role, const std::vector<std::string>& claimed) {
  std::vector<sdk::Scope> scopes;
  for (sdk::Scope scope : default_scopes(role))
    for (const std::string& name : claimed)
      if (sdk::parse_scope(name) == scope) {
        scopes.push_back(scope);
        break;
      }
  return scopes;
}

}  // namespace rcand
