// RCAN roles and scopes (docs/protocol.md §2).
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace rcand::sdk {

enum class Role : int { Guest = 1, User = 2, Leasee = 3, Owner = 4, Creator = 5 };

enum class Scope { None, Status, Control, Config, Training, Admin };

// Case-insensitive: "owner", "OWNER" and "Owner" are one role.
std::optional<Role> parse_role(std::string_view name) noexcept;
std::string_view role_name(Role role) noexcept;  // upper case, e.g. "OWNER"

std::optional<Scope> parse_scope(std::string_view name) noexcept;
std::string_view scope_name(Scope scope) noexcept;  // lower case, e.g. "control"

// The lowest role whose default scopes include `scope` (docs/protocol.md §2 table).
Role minimum_role(Scope scope) noexcept;
inline bool role_grants(Role role, Scope scope) noexcept {
  return static_cast<int>(role) >= static_cast<int>(minimum_role(scope));
}

}  // namespace rcand::sdk

#include "rcand/sdk/scope_inline.hpp"
