// The default scopes of each role (notes §2 table), derived from sdk::minimum_role so the two never disagree.
#pragma once

#include <vector>

#include "rcand/sdk/scope.hpp"

namespace rcand::kernel {

// In table order: status, control, config, training, admin (never Scope::None).
std::vector<sdk::Scope> default_scopes(sdk::Role role);

}  // namespace rcand::kernel
