#include <doctest/doctest.h>

#include <sys/wait.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "jwt_helpers.hpp"
#include "kernel/auth/authenticator.hpp"
#include "libs/rcan/crypto.hpp"
#include "libs/rcan/jwt.hpp"
#include "libs/rcan/secret_file.hpp"
#include "temp_dir.hpp"
#include "token_command.hpp"

using namespace rcand;
using namespace rcand::kernel;
using rcand::sdk::Role;
using rcand::sdk::Scope;
namespace fs = std::filesystem;

namespace {

using rcand::test::TempDir;

struct Run {
  int code = -1;
  std::string out, err;
};

Run token(std::vector<std::string> args, const std::string& stdin_text = {}) {
  std::istringstream in(stdin_text);
  std::ostringstream out, err;
  Run run;
  run.code = rcand::rcanctl::run_token(args, in, out, err);
  run.out = out.str();
  run.err = err.str();
  return run;
}

std::int64_t now_s() {
  return std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

Authenticator verifier(const std::string& secret) {
  AuthSettings s;
  s.jwt_secret = secret;
  s.robot_ruri = auth_test::kRobotRuri;
  s.device_id = auth_test::kDeviceId;
  return Authenticator(s);
}

const std::string kFileSecret = "s3cret-from-file";

// A JWT secret as an operator keeps it: readable by its owner alone (others get a warning on stderr).
fs::path write_secret(const TempDir& dir, const std::string& content) {
  const fs::path file = dir.write("jwt.key", content);
  fs::permissions(file, fs::perms::owner_read | fs::perms::owner_write);
  return file;
}

}  // namespace

TEST_CASE("read_secret_file strips the trailing newline and refuses empty or missing files") {
  const TempDir dir{"rcand-auth-test"};
  CHECK(read_secret_file(dir.write("a", "abc\n")).secret == "abc");
  CHECK(read_secret_file(dir.write("b", "abc\r\n")).secret == "abc");
  CHECK(read_secret_file(dir.write("c", "a b\nc")).secret == "a b\nc");  // only the trailing newline goes
  const SecretFile empty = read_secret_file(dir.write("d", "\n"));
  CHECK_FALSE(empty.secret);
  CHECK(empty.error.find("empty") != std::string::npos);
  CHECK(read_secret_file(dir.path() / "missing").error.find("cannot read") != std::string::npos);
  CHECK(read_secret_file(dir.path()).error.find("directory") != std::string::npos);
  CHECK(read_secret_file(dir.write("e", "topsecret\n")).error.find("topsecret") == std::string::npos);
  // Other users able to read it: still used, with a warning naming the file and the chmod (never the secret).
  const auto shared = dir.write("f", "topsecret\n");
  std::filesystem::permissions(shared, std::filesystem::perms(0644));
  const SecretFile exposed = read_secret_file(shared);
  CHECK(exposed.secret == "topsecret");
  CHECK(exposed.warning.find("other users may read") != std::string::npos);
  CHECK(exposed.warning.find("chmod 600 '" + shared.string() + "'") != std::string::npos);
  CHECK(exposed.warning.find("topsecret") == std::string::npos);
  std::filesystem::permissions(shared, std::filesystem::perms(0600));
  CHECK(read_secret_file(shared).warning.empty());
}

TEST_CASE("the repository's development secret is used without a warning whatever its mode; a real one still warns") {
  // A fresh clone: git keeps no mode, so config/dev-jwt.secret is 0644 there (README's first commands use it).
  const TempDir dir{"rcand-auth-test"};
  const fs::path development = dir.path() / "dev-jwt.secret";
  fs::copy_file(fs::path(RCAND_SOURCE_DIR) / "config" / "dev-jwt.secret", development);
  fs::permissions(development, fs::perms(0644));
  const SecretFile read = read_secret_file(development);
  REQUIRE(read.secret);
  CHECK(read.development);
  CHECK(read.warning.empty());
  const Run issued = token({"issue", "--secret-file", development.string(), "--role", "owner"});
  CHECK(issued.code == 0);
  CHECK(issued.err.empty());
  // Any other secret with that mode (even one byte away from it) still warns.
  const fs::path real = dir.write("real.secret", *read.secret + "x\n");
  fs::permissions(real, fs::perms(0644));
  CHECK_FALSE(read_secret_file(real).development);
  CHECK(read_secret_file(real).warning.find("other users may read") != std::string::npos);
  const Run warned = token({"issue", "--secret-file", real.string(), "--role", "owner"});
  CHECK(warned.code == 0);
  CHECK(warned.err.find("warning: --secret-file: other users may read or write this secret") != std::string::npos);
}

TEST_CASE("token issue: defaults give the role's scopes, aud rcan://*, a 1 h lifetime") {
  const TempDir dir{"rcand-auth-test"};
  const fs::path secret = write_secret(dir, kFileSecret + "\n");
  const Run run = token({"issue", "--secret-file", secret.string(), "--role", "user"});
  REQUIRE(run.code == 0);
  CHECK(run.err.empty());
  REQUIRE(run.out.size() > 1);
  fs::permissions(secret, fs::perms(0644));  // readable by others: still issued, with a warning naming the fix
  const Run exposed = token({"issue", "--secret-file", secret.string(), "--role", "user"});
  CHECK(exposed.code == 0);
  CHECK(exposed.err.find("warning: --secret-file: other users may read or write this secret") != std::string::npos);
  CHECK(exposed.err.find(kFileSecret) == std::string::npos);
  CHECK(run.out.back() == '\n');
  const std::string jwt = run.out.substr(0, run.out.size() - 1);
  CHECK(jwt.find('\n') == std::string::npos);

  const auto claims = verify_jwt_hs256(jwt, kFileSecret, now_s());  // the file's newline is not part of the key
  REQUIRE(std::holds_alternative<JwtClaims>(claims));
  const JwtClaims& c = std::get<JwtClaims>(claims);
  CHECK(c.sub == "rcanctl");
  CHECK(c.iss == "rcanctl");
  CHECK(c.role == "USER");
  CHECK(c.aud == std::vector<std::string>{"rcan://*"});
  CHECK(c.scope == std::vector<std::string>{"status", "control"});
  CHECK(c.exp - c.iat == 3600);
  CHECK_FALSE(c.fleet);

  const Authenticator auth = verifier(kFileSecret);
  CHECK(std::holds_alternative<Principal>(auth.authorize(jwt, Scope::Control, now_s())));
  CHECK(std::get<AuthError>(auth.authorize(jwt, Scope::Config, now_s())).status == 403);
}

TEST_CASE("token issue: every option") {
  const TempDir dir{"rcand-auth-test"};
  const fs::path secret = write_secret(dir, kFileSecret);
  const Run run = token({"issue", "--secret-file", secret.string(), "--role", "Creator", "--ttl", "15m", "--aud",
                         "rcan://acme.*.*", "--sub", "ops", "--scope", "status,admin", "--fleet=1a2b3c4d,deadbeef"});
  REQUIRE(run.code == 0);
  const auto claims = verify_jwt_hs256(run.out.substr(0, run.out.size() - 1), kFileSecret, now_s());
  REQUIRE(std::holds_alternative<JwtClaims>(claims));
  const JwtClaims& c = std::get<JwtClaims>(claims);
  CHECK(c.sub == "ops");
  CHECK(c.role == "CREATOR");
  CHECK(c.aud == std::vector<std::string>{"rcan://acme.*.*"});
  CHECK(c.scope == std::vector<std::string>{"status", "admin"});
  CHECK(c.exp - c.iat == 900);
  CHECK(c.fleet == std::vector<std::string>{"1a2b3c4d", "deadbeef"});

  for (const auto& [ttl, seconds] : {std::pair{"30s", 30}, {"1h", 3600}, {"7d", 7 * 86400}}) {
    const Run r = token({"issue", "--secret-file", secret.string(), "--role", "guest", "--ttl", ttl});
    REQUIRE(r.code == 0);
    const auto parsed = verify_jwt_hs256(r.out.substr(0, r.out.size() - 1), kFileSecret, now_s());
    REQUIRE(std::holds_alternative<JwtClaims>(parsed));
    CHECK(std::get<JwtClaims>(parsed).exp - std::get<JwtClaims>(parsed).iat == seconds);
  }
}

TEST_CASE("token issue: usage and input errors exit 2 with a clear message and no token") {
  const TempDir dir{"rcand-auth-test"};
  const fs::path secret = write_secret(dir, kFileSecret + "\n");
  const fs::path empty = dir.write("empty.key", "\n");
  const std::string s = secret.string();
  struct Case {
    std::vector<std::string> args;
    const char* says;
  };
  for (const Case& c : std::vector<Case>{
           {{"issue", "--role", "owner"}, "--secret-file"},
           {{"issue", "--secret-file", s}, "--role"},
           {{"issue", "--secret-file", s, "--role", "wizard"}, "not a role"},
           {{"issue", "--secret-file", empty.string(), "--role", "owner"}, "empty"},
           {{"issue", "--secret-file", (dir.path() / "nope").string(), "--role", "owner"}, "cannot read"},
           {{"issue", "--secret-file", s, "--role", "owner", "--ttl", "10"}, "--ttl"},
           {{"issue", "--secret-file", s, "--role", "owner", "--ttl", "-1h"}, "--ttl"},
           {{"issue", "--secret-file", s, "--role", "owner", "--ttl", "0s"}, "--ttl"},
           {{"issue", "--secret-file", s, "--role", "owner", "--ttl", "1w"}, "--ttl"},
           {{"issue", "--secret-file", s, "--role", "owner", "--ttl", "99999999999d"}, "--ttl"},
           {{"issue", "--secret-file", s, "--role", "owner", "--aud", "http://x"}, "--aud"},
           {{"issue", "--secret-file", s, "--role", "owner", "--scope", "status,fly"}, "'fly' is not a scope"},
           {{"issue", "--secret-file", s, "--role", "user", "--scope", "config"}, "needs role OWNER"},
           {{"issue", "--secret-file", s, "--role", "owner", "--scope", ","}, "no scope"},
           {{"issue", "--secret-file", s, "--role", "owner", "--fleet", ""}, "no device id"},
           {{"issue", "--secret-file", s, "--role", "owner", "--bogus", "1"}, "unknown option '--bogus'"},
           {{"issue", "--secret-file", s, "--role"}, "--role: 1 required TEXT missing"},
           {{"frobnicate"}, "unknown action"},
           {{}, "subcommand is required"},
       }) {
    const Run run = token(c.args);
    INFO("args: ", doctest::toString(c.args.size()), " says: ", c.says, " stderr: ", run.err);
    CHECK(run.code == 2);
    CHECK(run.out.empty());
    CHECK(run.err.find(c.says) != std::string::npos);
    CHECK(run.err.find(kFileSecret) == std::string::npos);
  }
  const Run help = token({"--help"});
  CHECK(help.code == 0);
  CHECK(help.out.find("rcanctl token") != std::string::npos);
  CHECK(help.out.find("issue") != std::string::npos);
  const Run issue_help = token({"issue", "--help"});  // every option, from the table that parses them
  CHECK(issue_help.code == 0);
  for (const char* option : {"--secret-file", "--role", "--ttl", "--aud", "--sub", "--scope", "--fleet"})
    CHECK_MESSAGE(issue_help.out.find(option) != std::string::npos, option);
}

TEST_CASE("token hash and token new") {
  const Run hashed = token({"hash"}, "my-token\n");
  REQUIRE(hashed.code == 0);
  CHECK(hashed.out == sha256_hex("my-token") + "\n");
  CHECK(token({"hash"}, "").code == 2);
  CHECK(token({"hash", "extra"}, "x").code == 2);

  const Run fresh = token({"new"});
  REQUIRE(fresh.code == 0);
  REQUIRE(fresh.out.size() == 65);
  const std::string value = fresh.out.substr(0, 64);
  CHECK(value.find_first_not_of("0123456789abcdef") == std::string::npos);
  CHECK(fresh.err == "sha256: " + sha256_hex(value) + "\n");
  CHECK(token({"new"}).out != fresh.out);

  // The pair works end to end: the printed hash configures a token the Authenticator accepts.
  AuthSettings s;
  s.tokens = {{"peer", Role::User, token({"hash"}, value).out.substr(0, 64)}};
  const Authenticator auth(s);
  CHECK(std::holds_alternative<Principal>(auth.authorize(value, Scope::Control, now_s())));
}

TEST_CASE("the built rcanctl issues a token the Authenticator accepts") {
#ifndef RCANCTL_PATH
  MESSAGE("rcanctl is not a target in this build; skipped");
#else
  if (!fs::exists(RCANCTL_PATH)) {
    MESSAGE("rcanctl is not built (" RCANCTL_PATH "); skipped");
    return;
  }
  const TempDir dir{"rcand-auth-test"};
  const fs::path secret = write_secret(dir, kFileSecret + "\n");
  const std::string command = std::string("'") + RCANCTL_PATH + "' token issue --secret-file '" + secret.string() +
                              "' --role owner --aud " + auth_test::kRobotRuri + " --fleet " + auth_test::kDeviceId;
  FILE* pipe = popen(command.c_str(), "r");
  REQUIRE(pipe != nullptr);
  std::string out;
  char buffer[512];
  while (std::size_t n = std::fread(buffer, 1, sizeof buffer, pipe)) out.append(buffer, n);
  const int status = pclose(pipe);
  REQUIRE(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 0);
  REQUIRE(!out.empty());
  CHECK(out.back() == '\n');
  const std::string jwt = out.substr(0, out.size() - 1);

  const Authenticator auth = verifier(kFileSecret);
  const auto result = auth.authorize(jwt, Scope::Config, now_s());
  REQUIRE(std::holds_alternative<Principal>(result));
  CHECK(std::get<Principal>(result).role == Role::Owner);
  CHECK(std::get<Principal>(result).name == "rcanctl");
  CHECK(std::get<AuthError>(auth.authorize(jwt, Scope::Admin, now_s())).status == 403);
  CHECK(std::get<AuthError>(verifier("another secret").authorize(jwt, Scope::Status, now_s())).status == 401);

  // Usage errors exit 2.
  const int bad = std::system((std::string("'") + RCANCTL_PATH + "' token issue --role owner 2>/dev/null").c_str());
  REQUIRE(WIFEXITED(bad));
  CHECK(WEXITSTATUS(bad) == 2);
  const int none = std::system((std::string("'") + RCANCTL_PATH + "' 2>/dev/null").c_str());
  REQUIRE(WIFEXITED(none));
  CHECK(WEXITSTATUS(none) == 2);
#endif
}
