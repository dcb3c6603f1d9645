// The default scopes of each role (docs/protocol.md §2 table), derived from sdk::minimum_role so the two never disagree.
#pragma once

#include <string>
#include <vector>

#include "rcand/sdk/scope.hpp"

namespace rcand {

// In table order: status, control, config, training, admin (never Scope::None).
std::vector<sdk::Scope> default_scopes(sdk::Role role);

// The scopes a credential that names both grants: the claimed ones the role allows (claim ∩ role), in table order.
// Every transport's principal gets its scopes here, so a GUEST whose JWT claims "control" has status only, over
// HTTP, /ws/r2r and every R2R message alike. Unknown names are someone else's extension and are ignored.
std::vector<sdk::Scope> granted_scopes(sdk::Role role, const std::vector<std::string>& claimed);

}  // namespace rcand
