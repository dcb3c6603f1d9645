#include "libs/rcan/role_scopes.hpp"

namespace rcand {

std::vector<sdk::Scope> default_scopes(sdk::Role role) {
  std::vector<sdk::Scope> scopes;
  for (sdk::Scope scope : {sdk::Scope::Status, sdk::Scope::Control, sdk::Scope::Config, sdk::Scope::Training, sdk::Scope::Admin})
    if (sdk::role_grants(role, scope)) scopes.push_back(scope);
  return scopes;
}

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
