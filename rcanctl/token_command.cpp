#include "token_command.hpp"

#include <charconv>
#include <chrono>
#include <iostream>
#include <iterator>
#include <optional>
#include <string_view>
#include <vector>

#include "exit_codes.hpp"
#include "libs/rcan/crypto.hpp"
#include "libs/rcan/jwt.hpp"
#include "libs/rcan/role_scopes.hpp"
#include "libs/rcan/ruri.hpp"
#include "libs/rcan/secret_file.hpp"
#include "rcand/sdk/scope.hpp"

namespace rcand::rcanctl {
namespace {

namespace sdk = rcand::sdk;

constexpr std::string_view kTokenUsage =
    "usage: rcanctl token issue --secret-file FILE --role ROLE [--ttl 1h] [--aud RURI] [--sub NAME]\n"
    "                           [--scope a,b] [--fleet id,...]\n"
    "         print an HS256 JWT signed with the secret in FILE (trailing newline ignored).\n"
    "         ROLE: creator|owner|leasee|user|guest; --ttl: 30s, 15m, 1h, 7d (default 1h);\n"
    "         --aud default rcan://* (every robot); --sub default rcanctl; --scope default: the role's scopes.\n"
    "       rcanctl token hash    read a token on stdin, print its SHA-256 (for runtime.auth.tokens[].sha256)\n"
    "       rcanctl token new     print a new random token; its sha256 line for the config goes to stderr\n";

std::vector<std::string> split_list(std::string_view text) {
  std::vector<std::string> items;
  for (std::size_t start = 0; start <= text.size();) {
    std::size_t comma = text.find(',', start);
    if (comma == std::string_view::npos) comma = text.size();
    if (comma > start) items.emplace_back(text.substr(start, comma - start));
    start = comma + 1;
  }
  return items;
}

// "30s", "15m", "1h", "7d" -> seconds; nullopt when malformed, zero or beyond ten years.
std::optional<std::int64_t> parse_ttl(std::string_view text) {
  if (text.size() < 2) return std::nullopt;
  std::int64_t unit = 0;
  switch (text.back()) {
    case 's': unit = 1; break;
    case 'm': unit = 60; break;
    case 'h': unit = 3600; break;
    case 'd': unit = 86400; break;
    default: return std::nullopt;
  }
  const std::string_view digits = text.substr(0, text.size() - 1);
  std::int64_t count = 0;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), count);
  if (ec != std::errc{} || end != digits.data() + digits.size() || count <= 0) return std::nullopt;
  constexpr std::int64_t kMaxS = 10LL * 366 * 86400;
  if (count > kMaxS / unit) return std::nullopt;
  return count * unit;
}

std::string strip_trailing_newlines(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
  return text;
}

int issue(std::span<const std::string> args, std::ostream& out, std::ostream& err) {
  std::optional<std::string> secret_file, role_text, ttl_text, aud, sub, scope_text, fleet_text;
  const std::pair<std::string_view, std::optional<std::string>*> options[] = {
      {"--secret-file", &secret_file}, {"--role", &role_text}, {"--ttl", &ttl_text},       {"--aud", &aud},
      {"--sub", &sub},                 {"--scope", &scope_text}, {"--fleet", &fleet_text}};
  for (std::size_t i = 0; i < args.size(); ++i) {
    std::string_view word = args[i];
    if (word == "--help" || word == "-h") {
      out << kTokenUsage;
      return kExitOk;
    }
    std::optional<std::string> inline_value;
    if (const std::size_t eq = word.find('='); word.starts_with("--") && eq != std::string_view::npos) {
      inline_value = std::string(word.substr(eq + 1));
      word = word.substr(0, eq);
    }
    std::optional<std::string>* slot = nullptr;
    for (const auto& [name, target] : options)
      if (word == name) slot = target;
    if (slot == nullptr) {
      err << "rcanctl token issue: unknown option '" << word << "'\n" << kTokenUsage;
      return kExitUsage;
    }
    if (!inline_value) {
      if (i + 1 >= args.size()) {
        err << "rcanctl token issue: option '" << word << "' needs a value\n";
        return kExitUsage;
      }
      inline_value = args[++i];
    }
    *slot = std::move(inline_value);
  }

  if (!secret_file) {
    err << "rcanctl token issue: --secret-file FILE is required\n" << kTokenUsage;
    return kExitUsage;
  }
  if (!role_text) {
    err << "rcanctl token issue: --role ROLE is required (creator, owner, leasee, user or guest)\n";
    return kExitUsage;
  }
  const std::optional<sdk::Role> role = sdk::parse_role(*role_text);
  if (!role) {
    err << "rcanctl token issue: --role '" << *role_text
        << "' is not a role; use creator, owner, leasee, user or guest\n";
    return kExitUsage;
  }
  const std::optional<std::int64_t> ttl = parse_ttl(ttl_text.value_or("1h"));
  if (!ttl) {
    err << "rcanctl token issue: --ttl '" << *ttl_text
        << "' must be a positive number followed by s, m, h or d (for example 30s, 15m, 1h, 7d)\n";
    return kExitUsage;
  }

  rcand::JwtClaims claims;
  claims.role = std::string(sdk::role_name(*role));
  claims.sub = sub.value_or("rcanctl");
  claims.iss = "rcanctl";
  if (claims.sub.empty()) {
    err << "rcanctl token issue: --sub must not be empty\n";
    return kExitUsage;
  }
  claims.aud = {aud.value_or("rcan://*")};
  if (const rcand::RuriParse parsed = rcand::parse_ruri(claims.aud.front(), /*allow_wildcards=*/true); !parsed.ruri) {
    err << "rcanctl token issue: --aud: " << parsed.error << "\n";
    return kExitUsage;
  }
  if (scope_text) {
    for (const std::string& name : split_list(*scope_text)) {
      const std::optional<sdk::Scope> scope = sdk::parse_scope(name);
      if (!scope || *scope == sdk::Scope::None) {
        err << "rcanctl token issue: --scope '" << name
            << "' is not a scope; use status, control, config, training or admin\n";
        return kExitUsage;
      }
      if (!sdk::role_grants(*role, *scope)) {  // the robot would refuse it anyway: say so now
        err << "rcanctl token issue: --scope '" << name << "' needs role "
            << sdk::role_name(sdk::minimum_role(*scope)) << " or higher, but --role is " << claims.role << "\n";
        return kExitUsage;
      }
      claims.scope.emplace_back(sdk::scope_name(*scope));
    }
    if (claims.scope.empty()) {
      err << "rcanctl token issue: --scope lists no scope\n";
      return kExitUsage;
    }
  } else {
    for (sdk::Scope scope : rcand::default_scopes(*role)) claims.scope.emplace_back(sdk::scope_name(scope));
  }
  if (fleet_text) {
    claims.fleet = split_list(*fleet_text);
    if (claims.fleet->empty()) {
      err << "rcanctl token issue: --fleet lists no device id\n";
      return kExitUsage;
    }
  }

  const rcand::SecretFile secret = rcand::read_secret_file(*secret_file);
  if (!secret.secret) {
    err << "rcanctl token issue: --secret-file: " << secret.error << "\n";
    return kExitUsage;
  }
  if (!secret.warning.empty()) err << "rcanctl token issue: warning: --secret-file: " << secret.warning << "\n";
  claims.iat = std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  claims.exp = claims.iat + *ttl;
  out << rcand::issue_jwt_hs256(claims, *secret.secret) << "\n";
  return kExitOk;
}

int hash(std::span<const std::string> args, std::istream& in, std::ostream& out, std::ostream& err) {
  if (!args.empty()) {
    err << "rcanctl token hash: takes no arguments (the token is read from stdin)\n";
    return kExitUsage;
  }
  const std::string token = strip_trailing_newlines({std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()});
  if (token.empty()) {
    err << "rcanctl token hash: no token on stdin (try: rcanctl token new, or echo -n TOKEN | rcanctl token hash)\n";
    return kExitUsage;
  }
  out << rcand::sha256_hex(token) << "\n";
  return kExitOk;
}

int make_new(std::span<const std::string> args, std::ostream& out, std::ostream& err) {
  if (!args.empty()) {
    err << "rcanctl token new: takes no arguments\n";
    return kExitUsage;
  }
  const std::string token = rcand::random_hex(32);
  out << token << "\n";
  err << "sha256: " << rcand::sha256_hex(token) << "\n";  // paste under runtime.auth.tokens[]
  return kExitOk;
}

}  // namespace

int run_token(std::span<const std::string> args, std::istream& in, std::ostream& out, std::ostream& err) {
  try {
    if (args.empty()) {
      err << kTokenUsage;
      return kExitUsage;
    }
    const std::string_view action = args.front();
    const std::span<const std::string> rest = args.subspan(1);
    if (action == "--help" || action == "-h" || action == "help") {
      out << kTokenUsage;
      return kExitOk;
    }
    if (action == "issue") return issue(rest, out, err);
    if (action == "hash") return hash(rest, in, out, err);
    if (action == "new") return make_new(rest, out, err);
    err << "rcanctl token: unknown action '" << action << "'\n" << kTokenUsage;
    return kExitUsage;
  } catch (const std::exception& e) {
    err << "rcanctl token: " << e.what() << "\n";
    return kExitFailure;
  }
}

int run_token(std::span<const std::string> args) { return run_token(args, std::cin, std::cout, std::cerr); }

}  // namespace rcand::rcanctl
