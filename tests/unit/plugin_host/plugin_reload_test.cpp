// The kernel's two pieces of a plugin reload that need no running rcand: the reload gate (calls admitted before a
// reload finish first; calls during it are held out) and PluginHost::reopen (the library on disk now, not the image
// already mapped; a broken new version ends in a named failure state).
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <thread>

#include "kernel/plugins/guarded.hpp"
#include "kernel/plugins/plugin_host.hpp"
#include "kernel/plugins/reload_gate.hpp"
#include "stub_context.hpp"
#include "temp_dir.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using rcand::kernel::PluginHost;
using rcand::kernel::PluginState;
using rcand::kernel::ReloadGate;

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
  for (const auto& entry : fs::directory_iterator(fs::temp_directory_path()))  // the private copies are gone
    CHECK(entry.path().filename().string().find("rcand-" + std::to_string(::getpid()) + "-reload-") == std::string::npos);
}
