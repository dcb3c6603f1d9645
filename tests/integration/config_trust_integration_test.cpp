// A conf.d fragment another user could write is refused at start, by --check-config and by a SIGHUP reload (issue
// 28 item 5): it never reaches runtime.auth, so it cannot plant a token, open the robot or drop the owner's tokens.
// The refusal names the file and the chmod that fixes it; fixed, the same fragment loads.
#include <doctest/doctest.h>
#include <signal.h>

#include <filesystem>
#include <string>

#include "eventually.hpp"
#include "libs/rcan/crypto.hpp"
#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

// A fragment that replaces every token by one of the attacker's, with the CREATOR role.
const std::string kPlantedToken = "planted-creator-token";
std::string planting_fragment() {
  return json{
      {"runtime",
       {{"auth",
         {{"tokens",
           json::array({{{"principal", "mallory"}, {"role", "creator"}, {"sha256", rcand::sha256_hex(kPlantedToken)}}})}}}}}}
      .dump();
}

std::size_t trust_count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// SIGHUP, then the reload's log line.
void trust_reload(const RcandProcess& rcand) {
  const auto before = trust_count(rcand.stderr_text(), "config reload from");
  REQUIRE(::kill(rcand.pid(), SIGHUP) == 0);
  REQUIRE(eventually([&] { return trust_count(rcand.stderr_text(), "config reload from") > before; }));
}

int status_with(const RcandProcess& rcand, const std::string& token) {
  int status = 0;
  rcand.json("GET", "/api/status", token, "", &status);
  return status;
}

}  // namespace

TEST_CASE("config trust: a world-writable conf.d fragment is refused by SIGHUP, then loads once chmod'ed") {
  RcandProcess rcand(sim_config());
  REQUIRE(status_with(rcand, "owner-token") == 200);
  const auto fragment = rcand.dir().write("conf.d/90-planted.yaml", planting_fragment());
  fs::permissions(fragment, fs::perms::group_write | fs::perms::others_write, fs::perm_options::add);

  trust_reload(rcand);
  const auto log = rcand.stderr_text();
  CHECK(log.find(fragment.string() + ": error: refused") != std::string::npos);
  CHECK(log.find("chmod ") != std::string::npos);
  CHECK(log.find("invalid; still running on the previous config") != std::string::npos);
  CHECK(status_with(rcand, kPlantedToken) == 401);  // nothing of it applied
  CHECK(status_with(rcand, "owner-token") == 200);  // and nothing dropped

  TempDir::safe_mode(fragment);  // the admin's fix, as the message says
  trust_reload(rcand);
  CHECK(status_with(rcand, kPlantedToken) == 200);  // the same fragment, now trusted, applies
  CHECK(status_with(rcand, "owner-token") == 401);
}

TEST_CASE("config trust: rcand does not start, and --check-config fails, on a world-writable fragment") {
  TempDir dir;
  auto config = sim_config();
  config["runtime"]["state_dir"] = (dir.path() / "state").string();
  dir.write("jwt.secret", kJwtSecret);
  const auto file = dir.write("robot.rcan.yaml", config.dump());
  const auto fragment = dir.write("conf.d/90-planted.yaml", planting_fragment());
  fs::permissions(fragment, fs::perms::others_write, fs::perm_options::add);

  const auto check = run_tool(rcand_binary(), {"--check-config", file.string(), "--plugin-path", plugin_dir().string()});
  CHECK(check.exit_code == 1);
  CHECK(check.err.find(fragment.string() + ": error: refused") != std::string::npos);
  CHECK(check.err.find("chmod o-w '" + fragment.string() + "'") != std::string::npos);
  const auto start = run_tool(rcand_binary(), {"--config", file.string(), "--port", "0", "--plugin-path", plugin_dir().string()});
  CHECK(start.exit_code == 1);
  CHECK(start.err.find("chmod o-w '" + fragment.string() + "'") != std::string::npos);
  CHECK_FALSE(fs::exists(dir.path() / "state"));  // refused before anything was claimed or written
}
