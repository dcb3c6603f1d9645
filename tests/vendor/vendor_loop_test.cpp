// The vendor loop of sdk/README.md, run exactly as a vendor runs it but without touching the machine: the SDK
// component of this build tree installed into a scratch DESTDIR (as librcand-sdk-dev would install it), a plugin of
// each kind scaffolded by that prefix's rcand-plugin, configured against that prefix alone (CMAKE_PREFIX_PATH),
// built, unit-tested on the SDK's fake host, then served: the capability by this tree's rcand started through the
// plugin's own dev-run (port 0) and called over HTTP, and from its Debian package unpacked into a scratch root; the
// driver by rcand --check-plugins and by dev-run with teleop driving it. Everything lives in one temporary directory.
#include <doctest/doctest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include "rcand_process.hpp"

namespace fs = std::filesystem;
using rcand::test::ProcessResult;
using rcand::test::run_tool;

namespace {

std::string read_text(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

void require_ok(const ProcessResult& r, const std::string& what) {
  if (r.exit_code != 0) throw std::runtime_error(what + " failed (" + std::to_string(r.exit_code) + "):\n" + r.out + r.err);
}

// CMakeCache.txt's value of `name` (NAME:TYPE=value), empty when absent.
std::string cache_value(const fs::path& build, const std::string& name) {
  const std::string cache = read_text(build / "CMakeCache.txt");
  const auto at = cache.find("\n" + name + ":");
  if (at == std::string::npos) return {};
  const auto value = cache.find('=', at) + 1;
  return cache.substr(value, cache.find('\n', value) - value);
}

// The SDK as librcand-sdk-dev installs it, staged under a scratch DESTDIR; built once for every test case.
struct StagedSdk {
  rcand::test::TempDir scratch{"rcand-vendor"};
  fs::path prefix;  // <scratch>/stage<install prefix>: what the vendor's CMAKE_PREFIX_PATH names
  fs::path tool;    // <prefix>/bin/rcand-plugin
  std::string failure;

  StagedSdk() {
    try {
      const fs::path stage = scratch.path() / "stage";
      require_ok(run_tool("/usr/bin/env", {"DESTDIR=" + stage.string(), RCAND_CMAKE_COMMAND, "--install", RCAND_BINARY_DIR,
                                           "--component", "sdk"}),
                 "cmake --install --component sdk");
      prefix = stage / fs::path(RCAND_INSTALL_PREFIX).relative_path();
      tool = prefix / "bin/rcand-plugin";
    } catch (const std::exception& e) {
      failure = e.what();
    }
  }

  ProcessResult scaffold(const std::vector<std::string>& args) const { return run_tool(tool.string(), args); }

  // rcand-plugin new, then configure (against the staged prefix only), build and run the unit test; returns the
  // source directory (its build tree is <source>/build).
  fs::path make_plugin(const std::string& id, const std::string& kind) const {
    const fs::path source = scratch.path() / (kind + "-plugin");
    require_ok(scaffold({"new", id, "--kind", kind, "--dir", source.string()}), "rcand-plugin new " + id);
    const fs::path build = source / "build";
    require_ok(run_tool(RCAND_CMAKE_COMMAND, {"-S", source.string(), "-B", build.string(), "-G", RCAND_CMAKE_GENERATOR,
                                              std::string("-DCMAKE_MAKE_PROGRAM=") + RCAND_MAKE_PROGRAM,
                                              std::string("-DCMAKE_CXX_COMPILER=") + RCAND_CXX_COMPILER,
                                              "-DCMAKE_PREFIX_PATH=" + prefix.string(), "-DCMAKE_INSTALL_PREFIX=/usr",
                                              // dev-run: this tree's rcand and plugins instead of the installed rcand package's
                                              "-DRCAND_EXECUTABLE=" + rcand::test::rcand_binary(),
                                              "-DRCAND_DEV_PLUGIN_PATHS=" + rcand::test::plugin_dir().string()}),
               "configuring " + id);
    // A compile is slow, not hung, on a loaded 2-core machine: ctest's own 600 s timeout is the limit that matters.
    require_ok(run_tool(RCAND_CMAKE_COMMAND, {"--build", build.string(), "-j2"}, {}, std::chrono::seconds(540)),
               "building " + id);
    return source;
  }
};

StagedSdk& staged_sdk() {
  static StagedSdk sdk;
  return sdk;
}

#define REQUIRE_SDK(sdk)         \
  StagedSdk& sdk = staged_sdk(); \
  if (!sdk.failure.empty()) FAIL(sdk.failure)

// rcand started through the plugin's own dev-run script, on port 0. The harness's launcher runs `sh -c <script>`
// with rcand's arguments as $0...; the script ignores them and runs dev-run, which execs rcand (same pid).
rcand::test::RcandProcess dev_run(const fs::path& source) {
  const std::string script = "exec '" + (source / "build/dev-run").string() + "' --port 0";
  return rcand::test::RcandProcess(nlohmann::json::object(), {"/bin/sh", "-c", script}, "127.0.0.1");
}

}  // namespace

TEST_CASE("the installed SDK has rcand-plugin, and it refuses bad ids, unknown kinds and existing directories") {
  REQUIRE_SDK(sdk);
  REQUIRE(fs::is_regular_file(sdk.tool));
  for (const char* id :
       {"rcand.lidar", "org.rcand.lidar", "com.acme", "com.Acme.lidar", "com.acme.3d", "com..lidar", "com.acme.li dar"}) {
    const auto r = sdk.scaffold({"new", id, "--kind", "capability", "--dir", (sdk.scratch.path() / "refused").string()});
    INFO(id, ": ", r.err);
    CHECK(r.exit_code == 2);
    CHECK(r.err.find("invalid id") != std::string::npos);
  }
  CHECK_FALSE(fs::exists(sdk.scratch.path() / "refused"));
  CHECK(sdk.scaffold({"new", "com.acme.lidar", "--kind", "sensor"}).exit_code == 2);
  CHECK(sdk.scaffold({"new", "com.acme.lidar"}).exit_code == 2);

  const fs::path taken = sdk.scratch.path() / "taken";
  fs::create_directories(taken);
  std::ofstream(taken / "CMakeLists.txt") << "# the vendor's own\n";
  const auto r = sdk.scaffold({"new", "com.acme.lidar", "--kind", "capability", "--dir", taken.string()});
  INFO(r.err);
  CHECK(r.exit_code == 1);
  CHECK(r.err.find("refusing to overwrite") != std::string::npos);
  CHECK(read_text(taken / "CMakeLists.txt") == "# the vendor's own\n");
}

TEST_CASE("a scaffolded capability builds and tests against the installed SDK alone, dev-run serves it, its .deb installs") {
  REQUIRE_SDK(sdk);
  const fs::path source = sdk.make_plugin("com.acme.lidar", "capability");
  const fs::path build = source / "build";
  // The plugin has its own names, derived from the id.
  CHECK(read_text(source / "lidar_capability.hpp").find("namespace acme::lidar {") != std::string::npos);
  const auto manifest = nlohmann::json::parse(read_text(source / "com.acme.lidar.json"));
  CHECK(manifest["id"] == "com.acme.lidar");
  CHECK(manifest["library"] == "acme_lidar.so");
  CHECK(manifest["abi"]["major"] == std::stoi(RCAND_ABI_MAJOR_TEXT));
  // Found the staged SDK and nothing else; optimised by default.
  CHECK(cache_value(build, "RcandSDK_DIR").rfind(sdk.prefix.string(), 0) == 0);
  CHECK(cache_value(build, "CMAKE_BUILD_TYPE") == "Release");
  CHECK(fs::is_regular_file(build / "plugins/acme_lidar.so"));

  const auto tests = run_tool(RCAND_CTEST_COMMAND, {"--test-dir", build.string(), "--output-on-failure"});
  INFO(tests.out, tests.err);
  CHECK(tests.exit_code == 0);
  CHECK(tests.out.find("100% tests passed, 0 tests failed out of 1") != std::string::npos);

  {
    auto robot = dev_run(source);
    int status = 0;
    const auto answer = robot.json("POST", "/api/cap/com.acme.lidar/message", "rcand-dev-user", R"({"text":"hello"})", &status);
    INFO(answer.dump(), robot.stderr_text());
    CHECK(status == 200);
    CHECK(answer == nlohmann::json{{"ok", true}, {"messages", 1}});
    CHECK(robot.json("GET", "/api/cap/com.acme.lidar/state", "rcand-dev-user")["last_message"] == "hello");
    robot.json("GET", "/api/cap/com.acme.lidar/state", "rcand-dev-guest", {}, &status);
    CHECK(status == 403);  // a custom capability needs scope control
    CHECK(robot.json("GET", "/api/discovery").dump().find("com.acme.lidar") != std::string::npos);
    CHECK(robot.stop() == 0);
  }
  {  // The same build in a process of its own (issue 34), by one setting in a conf.d fragment: the plugin cannot tell.
    const fs::path fragment = build / "dev/conf.d/50-isolated.yaml";
    fs::create_directories(fragment.parent_path());
    std::ofstream(fragment) << "runtime:\n  capabilities:\n    com.acme.lidar:\n      isolation: process\n";
    auto robot = dev_run(source);
    int status = 0;
    const auto answer =
        robot.json("POST", "/api/cap/com.acme.lidar/message", "rcand-dev-user", R"({"text":"isolated"})", &status);
    INFO(answer.dump(), robot.stderr_text());
    CHECK(status == 200);
    CHECK(answer == nlohmann::json{{"ok", true}, {"messages", 1}});
    CHECK(robot.json("GET", "/api/cap/com.acme.lidar/state", "rcand-dev-user")["last_message"] == "isolated");
    const auto process =
        robot.json("GET", "/api/status", "rcand-dev-owner")["capabilities"]["com.acme.lidar"]["status"]["process"];
    CHECK(process.value("isolation", "") == "process");
    CHECK(process.value("pid", 0) > 0);
    CHECK(process.value("pid", 0) != robot.pid());
    CHECK(robot.stop() == 0);
    fs::remove(fragment);
  }

  // The package, as its CMakeLists.txt makes it; installed (unpacked) and served from the packaged plugin directory.
  if (::access("/usr/bin/dpkg-deb", X_OK) != 0 || std::string(RCAND_LIBRARY_ARCHITECTURE).empty()) {
    MESSAGE("SKIPPED: the Debian package step (no dpkg-deb, or no multiarch directory)");
    return;
  }
  const fs::path debs = source / "debs";
  require_ok(run_tool(RCAND_CPACK_COMMAND, {"--config", (build / "CPackConfig.cmake").string(), "-B", debs.string()}), "cpack");
  fs::path deb;
  for (const auto& entry : fs::directory_iterator(debs))
    if (entry.path().extension() == ".deb") deb = entry.path();
  REQUIRE_MESSAGE(!deb.empty(), "cpack made no .deb in " << debs.string());
  CHECK(deb.filename().string().rfind("acme-lidar_0.1.0-1_", 0) == 0);  // debian/changelog's revision
  const auto depends = run_tool("/usr/bin/dpkg-deb", {"--field", deb.string(), "Depends"});
  CHECK(depends.out.find(std::string("rcand-plugin-abi-") + RCAND_ABI_MAJOR_TEXT + " (>= " + RCAND_ABI_MAJOR_TEXT + "." +
                         RCAND_ABI_MINOR_TEXT + ")") != std::string::npos);
  // Debian's own checks: no lintian errors (a copyright file, the changelog, a stripped library, a sane control file).
  if (::access("/usr/bin/lintian", X_OK) == 0) {
    const auto lint = run_tool("/usr/bin/lintian", {"--fail-on", "error", deb.string()});
    INFO(lint.out, lint.err);
    CHECK(lint.exit_code == 0);
    CHECK(lint.out.find("E: ") == std::string::npos);
  } else {
    MESSAGE("SKIPPED: lintian on the plugin's .deb (lintian is not installed: packaging/install-deps.sh --tests)");
  }
  const fs::path root = source / "root";
  REQUIRE(run_tool("/usr/bin/dpkg-deb", {"-x", deb.string(), root.string()}).exit_code == 0);
  const fs::path installed = root / "usr/lib" / RCAND_LIBRARY_ARCHITECTURE / "rcand/plugins";
  CHECK(fs::is_regular_file(installed / "com.acme.lidar.json"));
  CHECK(fs::is_regular_file(root / "usr/share/doc/acme-lidar/copyright"));
  CHECK(fs::is_regular_file(root / "usr/share/doc/acme-lidar/changelog.Debian.gz"));
  const auto served = run_tool(rcand::test::rcand_binary(), {"--check-plugins", "--plugin-path", installed.string()});
  INFO(served.out, served.err);
  CHECK(served.exit_code == 0);
  CHECK(served.out.find("com.acme.lidar") != std::string::npos);
}

TEST_CASE("a scaffolded driver builds and tests against the installed SDK alone, and rcand serves it") {
  REQUIRE_SDK(sdk);
  const fs::path source = sdk.make_plugin("com.acme.wheels", "driver");
  const fs::path build = source / "build";
  CHECK(read_text(source / "wheels_driver.hpp").find("namespace acme::wheels {") != std::string::npos);
  const auto tests = run_tool(RCAND_CTEST_COMMAND, {"--test-dir", build.string(), "--output-on-failure"});
  INFO(tests.out, tests.err);
  CHECK(tests.exit_code == 0);

  const auto checked = run_tool(rcand::test::rcand_binary(), {"--check-plugins", "--plugin-path", (build / "plugins").string()});
  INFO(checked.out, checked.err);
  CHECK(checked.exit_code == 0);
  CHECK(checked.out.find("com.acme.wheels") != std::string::npos);
  CHECK(checked.out.find("driver:acme_wheels") != std::string::npos);
  CHECK(checked.out.find("loaded") != std::string::npos);

  // dev-run's fragment adds the driver and points teleop at it: a move reaches the new driver's wheels.
  auto robot = dev_run(source);
  int status = 0;
  robot.json("POST", "/api/action", "rcand-dev-user", R"({"type":"move","linear":0.4,"duration_ms":60000})", &status);
  CHECK(status == 200);
  const auto wheels = robot.json("GET", "/api/drivers/wheels0", "rcand-dev-guest");
  INFO(wheels.dump(), robot.stderr_text());
  CHECK(wheels["plugin"] == "com.acme.wheels");
  CHECK(wheels["status"]["commands"].get<int>() >= 1);
  CHECK(wheels["status"]["left"] == doctest::Approx(0.2));  // 0.4 at the fragment's max_speed 0.5

  // The development loop: edited and rebuilt, the driver is reloaded into the running dev robot, wheels halted first.
  std::ofstream(source / "wheels_driver.hpp", std::ios::app) << "// edited\n";
  require_ok(run_tool(RCAND_CMAKE_COMMAND, {"--build", build.string()}), "rebuild");
  const auto reloaded = run_tool(rcand::test::rcanctl_binary(), {"plugins", "reload", "com.acme.wheels", "--port",
                                                                 std::to_string(robot.port()), "--token", "rcand-dev-owner"});
  INFO(reloaded.out, reloaded.err, robot.stderr_text());
  CHECK(reloaded.exit_code == 0);
  CHECK(reloaded.out.find("wheels0") != std::string::npos);
  const auto fresh = robot.json("GET", "/api/drivers/wheels0", "rcand-dev-guest");
  CHECK(fresh["state"] == "ok");
  CHECK(fresh["status"]["commands"] == 0);  // the new object; the old one was halted and destroyed
  REQUIRE(robot.request("POST", "/api/estop/clear", "rcand-dev-owner").status == 200);
  robot.json("POST", "/api/action", "rcand-dev-user", R"({"type":"move","linear":0.4,"duration_ms":60000})", &status);
  CHECK(status == 200);
  CHECK(robot.json("GET", "/api/drivers/wheels0", "rcand-dev-guest")["status"]["left"] == doctest::Approx(0.2));
}
