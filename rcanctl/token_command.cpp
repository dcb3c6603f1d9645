#include "token_command.hpp"

#include <charconv>
#include <chrono>
#include <iostream>
#include <iterator>
#include <optional>
#include <string_view>
#include <vector>

#include "command_line.hpp"
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

// What `rcanctl token issue` was given (unset: its default).
struct IssueArgs {
  std::optional<std::string> secret_file, role_text, ttl_text, aud, sub, scope_text, fleet_text;
};

void add_issue_options(CLI::App& issue, IssueArgs& a) {
  const auto text = [&issue](const char* name, std::optional<std::string>& into, const char* what) {
    issue.add_option_function<std::string>(
        name, [&into](const std::string& value) { into = value; }, what);
  };
  text("--secret-file", a.secret_file, "the HS256 secret (trailing newline ignored); required");
  text("--role", a.role_text, "creator, owner, leasee, user or guest; required");
  text("--ttl", a.ttl_text, "lifetime: 30s, 15m, 1h, 7d (default 1h)");
  text("--aud", a.aud, "the robot(s) it is for, an RURI (default rcan://*, every robot)");
  text("--sub", a.sub, "whom it names (default rcanctl)");
  text("--scope", a.scope_text, "scopes, comma-separated: status, control, config, training, admin (default the role's)");
  text("--fleet", a.fleet_text, "device ids it is limited to, comma-separated");
}

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

int issue(const IssueArgs& a, std::ostream& out, std::ostream& err) {
  const auto& [secret_file, role_text, ttl_text, aud, sub, scope_text, fleet_text] = a;
  if (!secret_file) {
    err << "rcanctl token issue: --secret-file FILE is required\n";
    return kExitUsage;
  }
  if (!role_text) {
    err << "rcanctl token issue: --role ROLE is required (creator, owner, leasee, user or guest)\n";
    return kExitUsage;
  }
  const std::optional<sdk::Role> role = sdk::parse_role(*role_text);
  if (!role) {
    err << "rcanctl token issue: --role '" << *role_text << "' is not a role; use creator, owner, leasee, user or guest\n";
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
        err << "rcanctl token issue: --scope '" << name << "' is not a scope; use status, control, config, training or admin\n";
        return kExitUsage;
      }
      if (!sdk::role_grants(*role, *scope)) {  // the robot would refuse it anyway: say so now
        err << "rcanctl token issue: --scope '" << name << "' needs role " << sdk::role_name(sdk::minimum_role(*scope))
            << " or higher, but --role is " << claims.role << "\n";
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

int hash(std::istream& in, std::ostream& out, std::ostream& err) {
  const std::string token = strip_trailing_newlines({std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()});
  if (token.empty()) {
    err << "rcanctl token hash: no token on stdin (try: rcanctl token new, or echo -n TOKEN | rcanctl token hash)\n";
    return kExitUsage;
  }
  out << rcand::sha256_hex(token) << "\n";
  return kExitOk;
}

int make_new(std::ostream& out, std::ostream& err) {
  const std::string token = rcand::random_hex(32);
  out << token << "\n";
  err << "sha256: " << rcand::sha256_hex(token) << "\n";  // paste under runtime.auth.tokens[]
  return kExitOk;
}

}  // namespace

int run_token(std::span<const std::string> args, std::istream& in, std::ostream& out, std::ostream& err) {
  try {
    const auto app = make_command_app("rcanctl token", "Tokens for rcand: JWTs, and pre-shared tokens with their hashes.",
                                      "Exit: 0 done, 1 failed, 2 usage.");
    IssueArgs issue_args;
    add_issue_options(*app->add_subcommand("issue", "print an HS256 JWT signed with the secret in --secret-file"), issue_args);
    app->add_subcommand("hash", "read a token on stdin, print its SHA-256 (for runtime.auth.tokens[].sha256)");
    app->add_subcommand("new", "print a new random token; its sha256 line for the config goes to stderr");
    app->require_subcommand(1);
    if (auto done = parse_command_line(*app, args, out, err)) return *done;
    const std::string action = app->get_subcommands().front()->get_name();
    if (action == "issue") return issue(issue_args, out, err);
    if (action == "hash") return hash(in, out, err);
    return make_new(out, err);
  } catch (const std::exception& e) {
    err << "rcanctl token: " << e.what() << "\n";
    return kExitFailure;
  }
}

int run_token(std::span<const std::string> args) { return run_token(args, std::cin, std::cout, std::cerr); }

}  // namespace rcand::rcanctl
