// The kernel's two pieces of a plugin reload that need no running rcand: the reload gate (calls admitted before a
// reload finish first; calls during it are held out) and PluginHost::reopen (the library on disk now, not the image
// already mapped; a broken new version ends in a named failure state), made safely (a private mkdtemp directory,
// never a predictable name in the shared temp dir) and bounded (each reload keeps an image mapped for good).
#include <doctest/doctest.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "kernel/plugins/guarded.hpp"
#include "kernel/plugins/plugin_host.hpp"
#include "libs/base/reload_gate.hpp"
#include "stub_context.hpp"
#include "temp_dir.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using rcand::ReloadGate;
using rcand::kernel::PluginHost;
using rcand::kernel::PluginState;

constexpr const char* kReloadFixture = "org.rcand.test.reload";

// Build variant `variant` of the reload fixture in `folder` under a manifest saying `version` (renamed into place).
void put_reload_fixture(const fs::path& folder, int variant, const std::string& version) {
  fs::create_directories(folder);
  const fs::path built = fs::path(RCAND_TEST_PLUGIN_DIR) / "reload" / ("rcand_test_reload_v" + std::to_string(variant) + ".so");
  fs::copy_file(built, folder / "next.so", fs::copy_options::overwrite_existing);
  fs::rename(folder / "next.so", folder / "reload.so");
  std::ofstream(folder / "reload.json") << json{{"id", kReloadFixture},
                                                {"version", version},
                                                {"library", "reload.so"},
                                                {"abi", {{"major", 1}, {"minor", 0}}},
                                                {"provides",
                                                 json::array({json{{"kind", "capability"}, {"name", kReloadFixture}}})}}
                                               .dump();
}

// The private reload directory reopen() made under `parent` ("" when there is none).
std::string reload_dir_name(const fs::path& parent) {
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(parent, ec))
    if (entry.path().filename().string().starts_with("plugin-reload-")) return entry.path().filename().string();
  return {};
}

// What the loaded version's GET /version answers, through a fresh instance of its capability.
std::string version_served(PluginHost& host) {
  auto* record = host.find(kReloadFixture);
  REQUIRE(record != nullptr);
  REQUIRE(record->capabilities.size() == 1);
  rcand::test::StubContext context(kReloadFixture);
  auto capability = record->capabilities[0].factory(context);
  REQUIRE(capability);
  const auto routes = capability->routes();
  REQUIRE_FALSE(routes.empty());
  return routes[0].handler(rcand::sdk::Request{}).body.value("version", "");
}

}  // namespace

TEST_CASE("reload gate: admitted calls are waited for; while closed nothing is admitted; open again admits") {
  auto gate = std::make_shared<ReloadGate>();
  auto pass = gate->enter();
  REQUIRE(pass);
  CHECK_FALSE(gate->close_and_drain(std::chrono::milliseconds(20)));  // a call is still in
  CHECK_FALSE(gate->enter());                                         // and nothing new gets in
  std::thread finishing([&pass] { pass.reset(); });
  CHECK(gate->close_and_drain(std::chrono::seconds(5)));
  finishing.join();
  gate->open();
  CHECK(gate->enter());
}

TEST_CASE("PluginHost::reopen serves the library on disk now; a broken new version is a named failure, fixable") {
  rcand::test::TempDir dir;
  const fs::path folder = dir.path() / "plugins";
  put_reload_fixture(folder, 1, "1.0.0");
  PluginHost host;
  host.set_reload_parent(dir.path());
  host.scan({folder});
  host.load_needed({kReloadFixture}, {});
  REQUIRE(host.find(kReloadFixture)->state == PluginState::Loaded);
  CHECK(version_served(host) == "1.0.0");

  put_reload_fixture(folder, 2, "2.0.0");
  host.reopen(kReloadFixture);
  REQUIRE(host.find(kReloadFixture)->state == PluginState::Loaded);
  CHECK(host.find(kReloadFixture)->version == "2.0.0");
  CHECK(version_served(host) == "2.0.0");  // not the image of 1.0.0 still mapped
  CHECK(host.find(kReloadFixture)->manifest->library == folder / "reload.so");
  CHECK(host.to_json()[0]["version"] == "2.0.0");

  put_reload_fixture(folder, 1, "2.0.0");  // the manifest says 2.0.0, the library is 1.0.0
  host.reopen(kReloadFixture);
  CHECK(host.find(kReloadFixture)->state == PluginState::ManifestMismatch);
  CHECK(host.find(kReloadFixture)->capabilities.empty());

  fs::remove(folder / "reload.so");
  host.reopen(kReloadFixture);
  CHECK(host.find(kReloadFixture)->state == PluginState::FailedToOpen);

  put_reload_fixture(folder, 1, "1.0.0");
  host.reopen(kReloadFixture);
  REQUIRE(host.find(kReloadFixture)->state == PluginState::Loaded);
  CHECK(version_served(host) == "1.0.0");
  for (const auto& entry : fs::directory_iterator(dir.path() / reload_dir_name(dir.path())))  // the copies are gone
    FAIL_CHECK("left behind: " << entry.path());
}

TEST_CASE("PluginHost::reopen copies into a private directory: nothing planted in the shared temp dir is followed") {
  rcand::test::TempDir dir;
  const fs::path folder = dir.path() / "plugins";
  put_reload_fixture(folder, 1, "1.0.0");
  // Symbolic links where the copy used to go (<tmp>/rcand-<pid>-reload-<n>-<library>), each to a file of the
  // victim's: a reload that followed one would overwrite it with the plugin.
  const auto victim = dir.write("victim", "the victim's data\n");
  const fs::path shared_tmp = fs::temp_directory_path();
  std::vector<fs::path> planted;
  for (int n = 1; n <= 64; ++n) {
    planted.push_back(shared_tmp / ("rcand-" + std::to_string(::getpid()) + "-reload-" + std::to_string(n) + "-reload.so"));
    std::error_code ec;
    fs::create_symlink(victim, planted.back(), ec);
  }
  {
    PluginHost host;
    host.set_reload_parent(dir.path() / "state");
    fs::create_directories(dir.path() / "state");
    host.scan({folder});
    host.load_needed({kReloadFixture}, {});
    put_reload_fixture(folder, 2, "2.0.0");
    host.reopen(kReloadFixture);
    std::ifstream in(victim);
    std::stringstream text;
    text << in.rdbuf();
    CHECK(text.str() == "the victim's data\n");  // no planted link was followed
    REQUIRE(host.find(kReloadFixture)->state == PluginState::Loaded);
    CHECK(version_served(host) == "2.0.0");
    const auto name = reload_dir_name(dir.path() / "state");  // the private directory: rcand's alone, emptied
    REQUIRE_FALSE(name.empty());
    struct stat info {};
    REQUIRE(::stat((dir.path() / "state" / name).c_str(), &info) == 0);
    CHECK((info.st_mode & 07777) == 0700);
    CHECK(fs::is_empty(dir.path() / "state" / name));
  }
  for (const auto& link : planted) fs::remove(link);
  CHECK(reload_dir_name(dir.path() / "state").empty());  // removed with the host
}

TEST_CASE("PluginHost::reopen uses $RUNTIME_DIRECTORY when set (systemd's RuntimeDirectory=)") {
  rcand::test::TempDir dir;
  const fs::path folder = dir.path() / "plugins";
  put_reload_fixture(folder, 1, "1.0.0");
  fs::create_directories(dir.path() / "runtime");
  ::setenv("RUNTIME_DIRECTORY", (dir.path() / "runtime").c_str(), 1);
  PluginHost host;
  host.set_reload_parent(dir.path() / "state-not-used");
  ::unsetenv("RUNTIME_DIRECTORY");
  host.scan({folder});
  host.load_needed({kReloadFixture}, {});
  put_reload_fixture(folder, 2, "2.0.0");
  host.reopen(kReloadFixture);
  CHECK(host.find(kReloadFixture)->state == PluginState::Loaded);
  CHECK_FALSE(reload_dir_name(dir.path() / "runtime").empty());
  CHECK_FALSE(fs::exists(dir.path() / "state-not-used"));
}

TEST_CASE("PluginHost::reopen is bounded: each one maps an image for good, so past kMaxReopens it is refused") {
  rcand::test::TempDir dir;
  const fs::path folder = dir.path() / "plugins";
  put_reload_fixture(folder, 1, "1.0.0");
  PluginHost host;
  host.set_reload_parent(dir.path());
  host.scan({folder});
  host.load_needed({kReloadFixture}, {});
  for (int i = 0; i < PluginHost::kMaxReopens; ++i) {
    CHECK(host.reopens_left(kReloadFixture) == PluginHost::kMaxReopens - i);
    host.reopen(kReloadFixture);
    REQUIRE(host.find(kReloadFixture)->state == PluginState::Loaded);
  }
  CHECK(host.reopens_left(kReloadFixture) == 0);
  host.reopen(kReloadFixture);
  const auto* record = host.find(kReloadFixture);
  CHECK(record->state == PluginState::FailedToOpen);
  CHECK(record->reason.find("each reload keeps its old version mapped") != std::string::npos);
  CHECK(record->hint.find("restart rcand") != std::string::npos);
}
