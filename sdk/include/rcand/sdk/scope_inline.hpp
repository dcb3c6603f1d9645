// Header-only definitions for scope.hpp, so plugins need no SDK library to link against.
#pragma once

#include <algorithm>
#include <array>
#include <cctype>

namespace rcand::sdk {
namespace detail {
inline bool iequals(std::string_view a, std::string_view b) noexcept {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
         });
}
inline constexpr std::array<std::pair<Role, std::string_view>, 5> kRoles{{{Role::Guest, "GUEST"},
                                                                          {Role::User, "USER"},
                                                                          {Role::Leasee, "LEASEE"},
                                                                          {Role::Owner, "OWNER"},
                                                                          {Role::Creator, "CREATOR"}}};
inline constexpr std::array<std::pair<Scope, std::string_view>, 6> kScopes{{{Scope::None, "none"},
                                                                            {Scope::Status, "status"},
                                                                            {Scope::Control, "control"},
                                                                            {Scope::Config, "config"},
                                                                            {Scope::Training, "training"},
                                                                            {Scope::Admin, "admin"}}};
}  // namespace detail

inline std::optional<Role> parse_role(std::string_view name) noexcept {
  for (const auto& [role, text] : detail::kRoles)
    if (detail::iequals(name, text)) return role;
  return std::nullopt;
}
inline std::string_view role_name(Role role) noexcept {
  for (const auto& [r, text] : detail::kRoles)
    if (r == role) return text;
  return "GUEST";
}
inline std::optional<Scope> parse_scope(std::string_view name) noexcept {
  for (const auto& [scope, text] : detail::kScopes)
    if (detail::iequals(name, text)) return scope;
  return std::nullopt;
}
inline std::string_view scope_name(Scope scope) noexcept {
  for (const auto& [s, text] : detail::kScopes)
    if (s == scope) return text;
  return "none";
}
inline Role minimum_role(Scope scope) noexcept {
  switch (scope) {
    case Scope::None:
    case Scope::Status: return Role::Guest;
    case Scope::Control: return Role::User;
    case Scope::Config:
    case Scope::Training: return Role::Owner;
    case Scope::Admin: return Role::Creator;
  }
  return Role::Creator;
}

}  // namespace rcand::sdk
