// The Debian packages, end to end and without touching the machine: cpack builds them from this build tree (or
// from a nested /usr-prefixed tree when this one is not /usr), dpkg-deb -x unpacks them into a scratch root, the
// vendor plugin com.acme.gripper is built out of tree against the unpacked SDK alone, and the unpacked rcand
// serves it beside the core plugin set. Skipped with a message where cpack or dpkg-deb is missing; the lintian
// check is skipped where lintian is missing.
#include <doctest/doctest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include "rcand_process.hpp"

namespace fs = std::filesystem;
using rcand::test::run_tool;

namespace {

std::optional<std::string> which(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "/usr/bin:/bin");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    const fs::path candidate = fs::path(dir) / name;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return std::nullopt;
}

std::string slurp(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The packages, built and unpacked once for every test case.
struct Packages {
  std::string skip;                     // non-empty: why the tests cannot run here
  std::string failure;                  // non-empty: building or unpacking failed (every test case fails)
  rcand::test::TempDir scratch;
  fs::path root;                        // every package unpacked here
  std::map<std::string, fs::path> debs;  // package name -> .deb
  std::map<std::string, fs::path> ddebs;  // package name -> its -dbgsym .ddeb (not unpacked into root)
  fs::path plugin_dir;                  // <root>/usr/lib/<multiarch>/rcand/plugins
  fs::path vendor_plugins;              // the out-of-tree com.acme.gripper build's plugin directory
  fs::path vendor_deb;                  // its Debian package, made by the template's CPack setup
  fs::path twin_plugins;                // com.other.gripper: the template renamed, C++ names unchanged
  std::string vendor_sdk_dir;           // RcandSDK_DIR the vendor build used
  std::string vendor_build_type;        // its CMAKE_BUILD_TYPE, chosen by the template when not given
  rcand::test::ProcessResult vendor_tests;  // ctest in the vendor build: the template's unit test
  std::optional<std::string> dpkg_deb;

  std::string field(const std::string& package, const std::string& name) const {
    const auto r = run_tool(*dpkg_deb, {"--field", debs.at(package).string(), name});
    return r.out;
  }
};

void require_ok(const rcand::test::ProcessResult& r, const std::string& what) {
  if (r.exit_code != 0) throw std::runtime_error(what + " failed (" + std::to_string(r.exit_code) + "):\n" + r.out + r.err);
}

fs::path package_build_tree(const std::string& cmake) {
  if (std::string(RCAND_INSTALL_PREFIX) == "/usr") return RCAND_BINARY_DIR;
  // This tree installs elsewhere, so its rcand has other default paths: package a /usr tree (incremental).
  MESSAGE("this build tree's prefix is " RCAND_INSTALL_PREFIX "; building the packages in a nested /usr tree");
  const fs::path nested = fs::path(RCAND_BINARY_DIR) / "packaging-build";
  require_ok(run_tool(cmake, {"-S", RCAND_SOURCE_DIR, "-B", nested.string(), "-G", RCAND_CMAKE_GENERATOR,
                              "-DCMAKE_INSTALL_PREFIX=/usr", "-DCMAKE_BUILD_TYPE=RelWithDebInfo",
                              "-DRCAND_BUILD_TESTS=OFF", "-DRCAND_BUILD_BENCH=OFF"}),
             "configuring the package tree");
  require_ok(run_tool(cmake, {"--build", nested.string(), "-j2"}), "building the package tree");
  return nested;
}

void build(Packages& p) {
  p.dpkg_deb = which("dpkg-deb");
  if (!p.dpkg_deb) {
    p.skip = "dpkg-deb not found (not a Debian machine): the package tests are skipped";
    return;
  }
  if (std::string(RCAND_LIBRARY_ARCHITECTURE).empty()) {
    p.skip = "CMake found no multiarch library architecture: the package tests are skipped";
    return;
  }
  const fs::path tree = package_build_tree(RCAND_CMAKE_COMMAND);
  const fs::path out = p.scratch.path() / "debs";
  require_ok(run_tool(RCAND_CPACK_COMMAND, {"-G", "DEB", "--config", (tree / "CPackConfig.cmake").string(), "-B", out.string()}),
             "cpack");
  p.root = p.scratch.path() / "root";
  for (const auto& entry : fs::directory_iterator(out)) {
    if (entry.path().extension() == ".ddeb") {
      const auto name = run_tool(*p.dpkg_deb, {"--field", entry.path().string(), "Package"});
      require_ok(name, "dpkg-deb --field");
      p.ddebs[name.out.substr(0, name.out.find('\n'))] = entry.path();
    }
    if (entry.path().extension() != ".deb") continue;
    const auto name = run_tool(*p.dpkg_deb, {"--field", entry.path().string(), "Package"});
    require_ok(name, "dpkg-deb --field");
    p.debs[name.out.substr(0, name.out.find('\n'))] = entry.path();
    require_ok(run_tool(*p.dpkg_deb, {"-x", entry.path().string(), p.root.string()}), "dpkg-deb -x");
  }
  p.plugin_dir = p.root / "usr/lib" / RCAND_LIBRARY_ARCHITECTURE / "rcand/plugins";

  // The vendor's build: the template from the unpacked SDK package, the unpacked SDK and nothing else of rcand.
  const fs::path vendor = p.scratch.path() / "vendor-build";
  const fs::path sdk_dir = p.root / "usr/lib" / RCAND_LIBRARY_ARCHITECTURE / "cmake/RcandSDK";
  const fs::path template_dir = p.root / "usr/share/rcand-sdk/template";
  auto build_vendor = [&](const fs::path& source, const fs::path& build_dir, bool with_tests) {
    require_ok(run_tool(RCAND_CMAKE_COMMAND,
                        {"-S", source.string(), "-B", build_dir.string(), "-G", RCAND_CMAKE_GENERATOR,
                         "-DRcandSDK_DIR=" + sdk_dir.string(), "-DCMAKE_PREFIX_PATH=" + (p.root / "usr").string(),
                         "-DCMAKE_INSTALL_PREFIX=/usr", std::string("-DBUILD_TESTING=") + (with_tests ? "ON" : "OFF")}),
               "configuring the vendor plugin from " + source.string());
    require_ok(run_tool(RCAND_CMAKE_COMMAND, {"--build", build_dir.string(), "-j2"}), "building the vendor plugin");
  };
  build_vendor(template_dir, vendor, true);  // with its unit test, which builds out of tree too
  p.vendor_plugins = vendor / "plugins";
  p.vendor_tests = run_tool(RCAND_CTEST_COMMAND, {"--test-dir", vendor.string(), "--output-on-failure"});
  // The vendor's package, as the template builds it.
  const fs::path vendor_debs = p.scratch.path() / "vendor-debs";
  require_ok(run_tool(RCAND_CPACK_COMMAND, {"--config", (vendor / "CPackConfig.cmake").string(), "-B", vendor_debs.string()}),
             "cpack of the vendor plugin");
  for (const auto& entry : fs::directory_iterator(vendor_debs))
    if (entry.path().extension() == ".deb") p.vendor_deb = entry.path();
  if (p.vendor_deb.empty()) throw std::runtime_error("cpack made no vendor .deb in " + vendor_debs.string());
  // A second vendor who started from the same template: ids, library and driver renamed as TEMPLATE.md says, every C++
  // name (namespace acme::gripper, class Gripper and its statics) left as it was.
  const fs::path twin = p.scratch.path() / "twin-source";
  fs::create_directories(twin);
  for (const auto& entry : fs::recursive_directory_iterator(template_dir)) {
    if (!entry.is_regular_file()) continue;
    std::string name = fs::relative(entry.path(), template_dir).string(), text = slurp(entry.path());
    for (auto* s : {&name, &text})
      for (const auto& [from, to] : {std::pair<std::string, std::string>{"com.acme.gripper", "com.other.gripper"},
                                     {"acme_gripper", "other_gripper"},
                                     {"acme-gripper", "other-gripper"}})
        for (auto at = s->find(from); at != std::string::npos; at = s->find(from, at + to.size()))
          s->replace(at, from.size(), to);
    fs::create_directories((twin / name).parent_path());
    std::ofstream(twin / name) << text;
  }
  build_vendor(twin, p.scratch.path() / "twin-build", false);
  p.twin_plugins = p.scratch.path() / "twin-build/plugins";
  const std::string cache = slurp(vendor / "CMakeCache.txt");
  for (auto [name, value] : {std::pair{"RcandSDK_DIR", &p.vendor_sdk_dir}, std::pair{"CMAKE_BUILD_TYPE", &p.vendor_build_type}}) {
    const auto at = cache.find("\n" + std::string(name) + ":");  // <name>:<type>=<value>
    if (at == std::string::npos) continue;
    const auto begin = cache.find('=', at) + 1;
    *value = cache.substr(begin, cache.find('\n', begin) - begin);
  }
}

// Built once for all test cases; a failure is recorded, not retried.
Packages& packages() {
  static Packages p;
  static bool built = false;
  if (!built) {
    built = true;
    try {
      build(p);
    } catch (const std::exception& e) {
      p.failure = e.what();
    }
  }
  return p;
}

#define REQUIRE_PACKAGES(p)          \
  Packages& p = packages();          \
  if (!p.skip.empty()) {             \
    MESSAGE("SKIPPED: " << p.skip);  \
    return;                          \
  }                                  \
  if (!p.failure.empty()) FAIL(p.failure)

}  // namespace

TEST_CASE("the kernel, SDK and core plugin packages are built, and the core set pulls nothing heavy") {
  REQUIRE_PACKAGES(p);
  for (const char* name : {"rcand", "librcand-sdk-dev", "rcand-plugins-core", "rcand-plugins-hw"})
    CHECK_MESSAGE(p.debs.count(name) == 1, name);
  CHECK_FALSE(p.debs.count("rcand-plugins-acme"));  // the vendor example is not a packaged plugin
  // A versioned Provides: a plugin package needs at least the minor it was built for.
  const std::string abi = std::string("rcand-plugin-abi-") + RCAND_ABI_MAJOR_TEXT;
  const std::string version = std::string(RCAND_ABI_MAJOR_TEXT) + "." + RCAND_ABI_MINOR_TEXT;
  CHECK(p.field("rcand", "Provides").find(abi + " (= " + version + ")") != std::string::npos);
  for (const char* plugins : {"rcand-plugins-core", "rcand-plugins-hw"})
    CHECK_MESSAGE(p.field(plugins, "Depends").find(abi + " (>= " + version + ")") != std::string::npos, plugins);
  for (const auto& entry : p.debs) {  // not a structured binding: CHECK_MESSAGE makes a lambda (clang 14)
    const std::string& name = entry.first;
    if (name.find("vision") != std::string::npos) continue;
    CHECK_MESSAGE(p.field(name, "Depends").find("opencv") == std::string::npos, name);
  }
}

TEST_CASE("the unpacked tree has the Debian layout, the systemd unit and the conffile") {
  REQUIRE_PACKAGES(p);
  CHECK(fs::is_regular_file(p.root / "usr/sbin/rcand"));
  CHECK(fs::is_regular_file(p.root / "usr/libexec/rcand/rcand-plugin-host"));  // isolation: process (issue 34)
  CHECK(fs::is_regular_file(p.root / "usr/bin/rcanctl"));
  CHECK(fs::is_regular_file(p.root / "etc/rcand/robot.rcan.yaml"));
  for (const char* file : {"rcand_teleop.so", "teleop.json", "rcand_nav.so", "nav.json", "rcand_fleet.so", "fleet.json",
                           "rcand_sim_drive.so", "sim_drive.json"})
    CHECK_MESSAGE(fs::is_regular_file(p.plugin_dir / file), file);
  CHECK_FALSE(fs::exists(p.plugin_dir / "acme_gripper.so"));
  const std::string pc = slurp(p.root / "usr/lib" / RCAND_LIBRARY_ARCHITECTURE / "pkgconfig/rcand-sdk.pc");
  CHECK(pc.find(std::string("abi_major=") + RCAND_ABI_MAJOR_TEXT) != std::string::npos);
  CHECK(pc.find(std::string("abi_minor=") + RCAND_ABI_MINOR_TEXT) != std::string::npos);
  CHECK(pc.find(std::string("plugindir=${prefix}/lib/") + RCAND_LIBRARY_ARCHITECTURE + "/rcand/plugins") != std::string::npos);

  const std::string unit = slurp(p.root / "lib/systemd/system/rcand.service");
  CHECK(unit.find("User=rcand") != std::string::npos);
  CHECK(unit.find("SupplementaryGroups=gpio i2c dialout video") != std::string::npos);
  CHECK(unit.find("Restart=on-failure") != std::string::npos);
  CHECK(unit.find("KillSignal=SIGTERM") != std::string::npos);  // rcand's e-stop path runs on SIGTERM
  CHECK(unit.find("ExecStart=/usr/sbin/rcand --config /etc/rcand/robot.rcan.yaml") != std::string::npos);
  const auto conffiles = run_tool(*p.dpkg_deb, {"--info", p.debs.at("rcand").string(), "conffiles"});
  CHECK(conffiles.out.find("/etc/rcand/robot.rcan.yaml") != std::string::npos);
}

TEST_CASE("the vendor plugin builds out of tree against the unpacked SDK only") {
  REQUIRE_PACKAGES(p);
  CHECK(fs::is_regular_file(p.vendor_plugins / "acme_gripper.so"));
  CHECK(fs::is_regular_file(p.vendor_plugins / "com.acme.gripper.json"));
  CHECK_MESSAGE(p.vendor_sdk_dir.rfind(p.root.string(), 0) == 0, "RcandSDK_DIR=" << p.vendor_sdk_dir);
  CHECK(p.vendor_build_type == "Release");  // optimised unless the vendor says otherwise
  // The template's unit test: built out of tree (rcand_add_plugin_test, the SDK's fake host) and passing.
  INFO(p.vendor_tests.out, p.vendor_tests.err);
  CHECK(p.vendor_tests.exit_code == 0);
  CHECK(p.vendor_tests.out.find("100% tests passed, 0 tests failed out of 1") != std::string::npos);
}

TEST_CASE("the unpacked rcand loads every packaged plugin and the vendor plugin") {
  REQUIRE_PACKAGES(p);
  const auto r = run_tool((p.root / "usr/sbin/rcand").string(), {"--check-plugins", "--plugin-path", p.plugin_dir.string(),
                                                                 "--plugin-path", p.vendor_plugins.string()});
  INFO(r.out, r.err);
  CHECK(r.exit_code == 0);
  for (const char* id :
       {"org.rcand.teleop", "org.rcand.nav", "org.rcand.fleet", "org.rcand.sim_drive", "org.rcand.arm", "org.rcand.chat",
        "org.rcand.pca9685", "org.rcand.dynamixel", "org.rcand.feetech", "org.rcand.gpio_motor", "com.acme.gripper"})
    CHECK_MESSAGE(r.out.find(id) != std::string::npos, id);
}

TEST_CASE("two plugins made from the template with identical C++ names load and serve side by side") {
  REQUIRE_PACKAGES(p);
  for (const fs::path& library : {p.vendor_plugins / "acme_gripper.so", p.twin_plugins / "other_gripper.so"}) {
    const auto exports = run_tool("/usr/bin/nm", {"-D", "--defined-only", library.string()});
    INFO(library.string(), ":\n", exports.out);
    CHECK(exports.out.find("rcand_plugin_entry_v") != std::string::npos);
    CHECK(std::count(exports.out.begin(), exports.out.end(), '\n') == 1);  // the entry symbol alone
  }
  const auto loaded =
      run_tool((p.root / "usr/sbin/rcand").string(),
               {"--check-plugins", "--plugin-path", p.vendor_plugins.string(), "--plugin-path", p.twin_plugins.string()});
  INFO(loaded.out, loaded.err);
  REQUIRE(loaded.exit_code == 0);
  auto config = rcand::test::sim_config();
  config["runtime"]["plugin_paths"] = {p.plugin_dir.string(), p.vendor_plugins.string(), p.twin_plugins.string()};
  config["drivers"].push_back({{"id", "gripper1"}, {"protocol", "other_gripper_sim"}});
  config["rcan_protocol"]["capabilities"].push_back("com.other.gripper");
  ::setenv("RCAND_UNPACKED", (p.root / "usr/sbin/rcand").c_str(), 1);
  rcand::test::RcandProcess process(config, {"/bin/sh", "-c", "exec \"$RCAND_UNPACKED\" \"$@\""}, "127.0.0.1");
  for (const char* id : {"com.acme.gripper", "com.other.gripper"}) {
    int status = 0;
    const auto grip =
        process.json("POST", std::string("/api/cap/") + id + "/grip", "owner-token", R"({"state":"close"})", &status);
    INFO(id, ": ", grip.dump());
    CHECK(status == 200);
  }
  const auto plugins = process.json("GET", "/api/plugins", "owner-token");
  INFO(plugins.dump());
  CHECK(plugins.dump().find("manifest-mismatch") == std::string::npos);
}

TEST_CASE("a vendor .deb from the template installs into the packaged plugin directory and depends on the ABI") {
  REQUIRE_PACKAGES(p);
  const auto depends = run_tool(*p.dpkg_deb, {"--field", p.vendor_deb.string(), "Depends"});
  const std::string abi_depends =
      std::string("rcand-plugin-abi-") + RCAND_ABI_MAJOR_TEXT + " (>= " + RCAND_ABI_MAJOR_TEXT + "." + RCAND_ABI_MINOR_TEXT + ")";
  CHECK(depends.out.find(abi_depends) != std::string::npos);
  const fs::path vendor_root = p.scratch.path() / "vendor-root";
  REQUIRE(run_tool(*p.dpkg_deb, {"-x", p.vendor_deb.string(), vendor_root.string()}).exit_code == 0);
  const fs::path installed = vendor_root / "usr/lib" / RCAND_LIBRARY_ARCHITECTURE / "rcand/plugins";
  CHECK(fs::is_regular_file(installed / "acme_gripper.so"));
  CHECK(fs::is_regular_file(installed / "com.acme.gripper.json"));
  const auto r = run_tool((p.root / "usr/sbin/rcand").string(),
                          {"--check-plugins", "--plugin-path", p.plugin_dir.string(), "--plugin-path", installed.string()});
  INFO(r.out, r.err);
  CHECK(r.exit_code == 0);
  CHECK(r.out.find("com.acme.gripper") != std::string::npos);
}

TEST_CASE("the vision plugin is a package of its own, the only one that depends on OpenCV, and it loads") {
  REQUIRE_PACKAGES(p);
  REQUIRE(p.debs.count("rcand-plugins-vision") == 1);
  const std::string abi = std::string("rcand-plugin-abi-") + RCAND_ABI_MAJOR_TEXT;
  const std::string depends = p.field("rcand-plugins-vision", "Depends");
  CHECK(depends.find(abi) != std::string::npos);
  // videoio through the video backend module; JPEG through libjpeg-turbo, not imgcodecs (issue 32).
  for (const char* library : {"libopencv-core", "libopencv-imgproc", "libopencv-videoio", "libjpeg62-turbo"})
    CHECK_MESSAGE(depends.find(library) != std::string::npos, library);
  CHECK(depends.find("libopencv-imgcodecs") == std::string::npos);
  CHECK(fs::is_regular_file(p.plugin_dir / "rcand_vision.so"));
  CHECK(fs::is_regular_file(p.plugin_dir / "vision.json"));
  // The module the plugin loads for a file, device or URL camera, from its own directory.
  CHECK(fs::is_regular_file(p.plugin_dir / "rcand_vision_videoio.so"));
  const auto r = run_tool((p.root / "usr/sbin/rcand").string(), {"--check-plugins", "--plugin-path", p.plugin_dir.string()});
  INFO(r.out, r.err);
  CHECK(r.exit_code == 0);
  CHECK(r.out.find("org.rcand.vision") != std::string::npos);
}

TEST_CASE("the shipped /etc/rcand config is valid against the core plugin set") {
  REQUIRE_PACKAGES(p);
  // As installed, plus what postinst generates (the JWT secret) and the unpacked plugin directory.
  const fs::path etc = p.scratch.path() / "etc-rcand";
  fs::create_directories(etc);
  std::ofstream(etc / "robot.rcan.yaml") << slurp(p.root / "etc/rcand/robot.rcan.yaml") << "  plugin_paths: ["
                                         << nlohmann::json(p.plugin_dir.string()).dump() << "]\n";
  std::ofstream(etc / "jwt.secret") << "0123456789abcdef0123456789abcdef\n";
  const auto r = run_tool((p.root / "usr/sbin/rcand").string(), {"--check-config", (etc / "robot.rcan.yaml").string()});
  INFO(r.out, r.err);
  CHECK(r.exit_code == 0);
}

TEST_CASE("the unpacked rcand serves com.acme.gripper beside the core set") {
  REQUIRE_PACKAGES(p);
  auto config = rcand::test::sim_config();
  config["runtime"]["plugin_paths"] = {p.plugin_dir.string(), p.vendor_plugins.string()};
  // The harness starts its launcher with the build tree's rcand as $0; run the unpacked one instead.
  ::setenv("RCAND_UNPACKED", (p.root / "usr/sbin/rcand").c_str(), 1);
  rcand::test::RcandProcess process(config, {"/bin/sh", "-c", "exec \"$RCAND_UNPACKED\" \"$@\""}, "127.0.0.1");
  const auto discovery = process.json("GET", "/api/discovery");
  INFO(discovery.dump());
  CHECK(discovery.dump().find("com.acme.gripper") != std::string::npos);
  int status = 0;
  const auto grip = process.json("POST", "/api/cap/com.acme.gripper/grip", "owner-token", R"({"state":"close"})", &status);
  INFO(grip.dump());
  CHECK(status == 200);
  CHECK(grip.value("ok", false));
}

TEST_CASE("lintian reports no errors on the packages") {
  REQUIRE_PACKAGES(p);
  const auto lintian = which("lintian");
  if (!lintian) {
    MESSAGE("SKIPPED: lintian not found (apt-get install lintian to run this check)");
    return;
  }
  for (const auto& entry : p.debs) {  // not a structured binding: INFO makes a lambda (clang 14)
    const std::string& name = entry.first;
    const auto r = run_tool(*lintian, {"--fail-on", "error", entry.second.string()});
    INFO(name, ":\n", r.out, r.err);
    CHECK(r.out.find("\nE: ") == std::string::npos);
    CHECK(r.out.rfind("E: ", 0) != 0);
    CHECK(r.exit_code == 0);
  }
}

TEST_CASE("the systemd unit is valid, supervised (notify, watchdog, reload) and hardened to exposure <= 3.0") {
  REQUIRE_PACKAGES(p);
  const std::string unit = slurp(p.root / "lib/systemd/system/rcand.service");
  // seccomp(2) and Landlock's calls are outside @system-service: without them an isolated capability's host could
  // not load its own filter and ruleset.
  const std::string filter =
      "SystemCallFilter=@system-service seccomp landlock_create_ruleset landlock_add_rule "
      "landlock_restrict_self";
  for (const char* line :
       {"Type=notify", "WatchdogSec=", "WatchdogSignal=SIGTERM", "ExecReload=/bin/kill -HUP $MAINPID", "DevicePolicy=closed",
        "DeviceAllow=char-gpiochip rw", "DeviceAllow=char-i2c rw", "LimitRTPRIO=10", filter.c_str()})
    CHECK_MESSAGE(unit.find(line) != std::string::npos, line);
  const auto analyze = which("systemd-analyze");
  if (!analyze) {
    MESSAGE("SKIPPED: systemd-analyze not found (apt-get install systemd to run this check)");
    return;
  }
  // verify needs ExecStart to exist: a copy pointing at the unpacked rcand. Any line it prints is a fault.
  rcand::test::TempDir dir;
  std::string copy = unit;
  copy.replace(copy.find("/usr/sbin/rcand"), std::string("/usr/sbin/rcand").size(), (p.root / "usr/sbin/rcand").string());
  const auto copied = dir.write("rcand.service", copy);
  const auto verified = run_tool(*analyze, {"verify", "--man=no", copied.string()});
  INFO(verified.out, verified.err);
  CHECK(verified.exit_code == 0);
  CHECK(verified.err.empty());
  const auto security = run_tool(*analyze, {"security", "--offline=true", copied.string()});
  const auto at = security.out.find("Overall exposure level for rcand.service: ");
  REQUIRE_MESSAGE(at != std::string::npos, security.out << security.err);
  const double exposure = std::stod(security.out.substr(at + std::string("Overall exposure level for rcand.service: ").size()));
  MESSAGE("systemd-analyze security: exposure " << exposure);
  CHECK(exposure <= 3.0);
}

TEST_CASE("the packaged binaries carry Debian's hardening: full RELRO, BIND_NOW, stack protector, fortified calls") {
  REQUIRE_PACKAGES(p);
  const auto readelf = which("readelf");
  if (!readelf) {
    MESSAGE("SKIPPED: readelf not found (binutils)");
    return;
  }
  for (const auto& binary : {p.root / "usr/sbin/rcand", p.root / "usr/bin/rcanctl", p.plugin_dir / "rcand_nav.so"}) {
    INFO(binary.string());
    const auto dynamic = run_tool(*readelf, {"--dynamic", "--wide", binary.string()}).out;
    CHECK(dynamic.find("BIND_NOW") != std::string::npos);
    CHECK(run_tool(*readelf, {"--program-headers", "--wide", binary.string()}).out.find("GNU_RELRO") != std::string::npos);
    const auto symbols = run_tool(*readelf, {"--dyn-syms", "--wide", binary.string()}).out;
    CHECK(symbols.find("__stack_chk_fail") != std::string::npos);
  }
  const auto symbols = run_tool(*readelf, {"--dyn-syms", "--wide", (p.root / "usr/sbin/rcand").string()}).out;
  CHECK(symbols.find("_chk@") != std::string::npos);  // at least one fortified libc call (e.g. __memcpy_chk)
}

// Debug symbols the Debian way: the packaged ELF files are stripped, and each package's -dbgsym .ddeb holds their
// debug info under /usr/lib/debug/.build-id/, named by the build id the stripped file still carries.
TEST_CASE("every binary package has a -dbgsym package with the debug info of its stripped files") {
  REQUIRE_PACKAGES(p);
  const auto readelf = which("readelf");
  if (!readelf) {
    MESSAGE("SKIPPED: readelf not found (binutils)");
    return;
  }
  const std::vector<std::pair<std::string, fs::path>> binaries{{"rcand", p.root / "usr/sbin/rcand"},
                                                               {"rcand-plugins-core", p.plugin_dir / "rcand_nav.so"},
                                                               {"rcand-plugins-hw", p.plugin_dir / "rcand_dynamixel.so"}};
  for (const auto& binary : binaries) {
    const std::string& package = binary.first;
    INFO(package, ": ", binary.second.string());
    REQUIRE(p.ddebs.count(package + "-dbgsym") == 1);
    const auto depends = run_tool(*p.dpkg_deb, {"--field", p.ddebs.at(package + "-dbgsym").string(), "Depends"}).out;
    CHECK(depends.find(package + " (=") != std::string::npos);
    const auto sections = run_tool(*readelf, {"--section-headers", "--wide", binary.second.string()}).out;
    CHECK(sections.find(".debug_info") == std::string::npos);  // stripped
    const auto notes = run_tool(*readelf, {"--notes", binary.second.string()}).out;
    const auto at = notes.find("Build ID: ");
    REQUIRE(at != std::string::npos);
    const std::string id = notes.substr(at + 10, notes.find_first_of(" \n", at + 10) - at - 10);
    REQUIRE(id.size() > 2);
    const fs::path debug_root = p.scratch.path() / ("dbgsym-" + package);
    REQUIRE(run_tool(*p.dpkg_deb, {"-x", p.ddebs.at(package + "-dbgsym").string(), debug_root.string()}).exit_code == 0);
    const fs::path debug_file = debug_root / "usr/lib/debug/.build-id" / id.substr(0, 2) / (id.substr(2) + ".debug");
    REQUIRE(fs::is_regular_file(debug_file));
    CHECK(run_tool(*readelf, {"--section-headers", "--wide", debug_file.string()}).out.find(".debug_info") != std::string::npos);
  }
}
