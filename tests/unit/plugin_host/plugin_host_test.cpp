#include "kernel/plugins/plugin_host.hpp"

#include <doctest/doctest.h>
#include <rcand/sdk/abi.h>

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "kernel/plugins/guarded.hpp"
#include "stub_context.hpp"
#include "temp_dir.hpp"

extern char** environ;

namespace fs = std::filesystem;
using nlohmann::json;
using rcand::kernel::guarded_call;
using rcand::kernel::PluginHost;
using rcand::kernel::PluginRecord;
using rcand::kernel::PluginState;

namespace {

using rcand::test::TempDir;

const fs::path kFixtures = RCAND_TEST_PLUGIN_DIR;

// Every capability a fixture provides, so that every fixture is opened.
const std::set<std::string> kAllCapabilities{
    "org.rcand.test.good",           "org.rcand.test.abi_major",          "org.rcand.test.newer_minor",
    "org.rcand.test.no_entry",       "org.rcand.test.mismatch",           "org.rcand.test.good_name_clash",
    "org.rcand.test.throws_in_register", "org.rcand.test.throws_in_handler", "org.rcand.test.undefined_symbol",
    "org.rcand.test.version_mismatch"};
const std::set<std::string> kAllDrivers{"org.rcand.test.fake_drive"};

const PluginRecord& by_manifest(const PluginHost& host, const std::string& file_name) {
  for (const auto& record : host.records())
    if (record->manifest_file.filename() == file_name) return *record;
  FAIL("no record for " << file_name);
  throw std::logic_error("unreachable");
}

// Whether a file with this name is mapped into this process (i.e. the library was dlopen'ed).
bool mapped(const std::string& library_name) {
  std::ifstream maps("/proc/self/maps");
  std::string line;
  while (std::getline(maps, line))
    if (line.size() >= library_name.size() + 1 && line.compare(line.size() - library_name.size() - 1, std::string::npos,
                                                               "/" + library_name) == 0)
      return true;
  return false;
}

rcand::sdk::Response call_route(rcand::sdk::Capability& capability, const std::string& path) {
  for (auto& route : capability.routes())
    if (route.method == "GET" && route.path == path) return route.handler(rcand::sdk::Request{});
  FAIL("no GET route " << path);
  return {};
}

std::unique_ptr<rcand::sdk::Capability> make_capability(const PluginRecord& record, const std::string& name) {
  for (const auto& capability : record.capabilities)
    if (capability.info.name == name) {
      rcand::test::StubContext context(record.id);
      std::string failure;
      auto made = rcand::kernel::guarded_result(record.id, "factory", failure, [&] { return capability.factory(context); });
      REQUIRE_MESSAGE(made.has_value(), failure);
      return std::move(*made);
    }
  FAIL("no registered capability " << name);
  return nullptr;
}


struct Expected {
  PluginState state;
  std::string reason;  // a substring: the key fact
  std::string hint;    // a substring
};

}  // namespace

TEST_CASE("every fixture plugin ends in its exact state with a reason and a hint") {
  PluginHost host;
  host.scan({kFixtures});
  host.load_needed(kAllCapabilities, kAllDrivers);

  const std::string lib_dir = kFixtures.string();
  const std::map<std::string, Expected> expected{
      {"good.json", {PluginState::Loaded, "", ""}},
      {"throws_in_handler.json", {PluginState::Loaded, "", ""}},
      {"driver.json", {PluginState::Loaded, "", ""}},
      {"abi_major.json", {PluginState::IncompatibleAbi, "built for ABI 2, kernel speaks 1", "rebuild against rcand-sdk 1.x"}},
      {"newer_minor.json",
       {PluginState::IncompatibleAbi,
        "built for ABI 1." + std::to_string(RCAND_ABI_MINOR + 1) + ", kernel speaks 1." + std::to_string(RCAND_ABI_MINOR),
        "upgrade rcand"}},
      {"no_entry.json", {PluginState::FailedToOpen, "no entry symbol rcand_plugin_entry_v1", "build it with RCAND_PLUGIN"}},
      {"mismatch.json",
       {PluginState::ManifestMismatch, "registered capability 'org.rcand.test.mismatch_extra' not in manifest", "\"provides\""}},
      {"good_duplicate.json",
       {PluginState::DuplicateId, "id 'org.rcand.test.good' is already used by " + lib_dir + "/good.json",
        lib_dir + "/good.json"}},
      {"good_alt_provider.json",
       {PluginState::InstalledNotEnabled, "capability 'org.rcand.test.good' is provided by org.rcand.test.good",
        "remove one of the providers"}},
      {"good_name_clash.json",
       {PluginState::RegistrationFailed, "capability 'org.rcand.test.good' is already registered by plugin org.rcand.test.good",
        "disable one"}},
      {"throws_in_register.json",
       {PluginState::RegistrationFailed, "register threw: register exploded on purpose", "register function"}},
      {"undefined_symbol.json",
       {PluginState::FailedToOpen, "undefined symbol: rcand_test_symbol_nobody_defines",
        "run `ldd -r " + lib_dir + "/rcand_test_undefined_symbol.so`"}},
      {"version_mismatch.json",
       {PluginState::ManifestMismatch, "descriptor version '2.0.0' differs from manifest version '1.0.0'",
        "RCAND_PLUGIN(id, version, ...)"}},
      {"bad_manifest.json",
       {PluginState::InvalidManifest, lib_dir + "/bad_manifest.json: (document): invalid JSON", "manifest.schema.json"}},
  };

  REQUIRE(host.records().size() == expected.size());
  for (const auto& entry : expected) {
    // Named references, not structured bindings: CAPTURE makes a lambda, and clang 14 cannot capture a binding.
    const auto& file = std::get<0>(entry); const auto& want = std::get<1>(entry);
    CAPTURE(file);
    const PluginRecord& record = by_manifest(host, file);
    CHECK(to_string(record.state) == to_string(want.state));
    CHECK_MESSAGE(record.reason.find(want.reason) != std::string::npos, record.reason);
    CHECK_MESSAGE(record.hint.find(want.hint) != std::string::npos, record.hint);
    if (want.state == PluginState::Loaded) {
      CHECK(record.reason.empty());
      CHECK(record.library != nullptr);
      CHECK(record.build_info.find("gcc") == 0);
    } else {
      CHECK_FALSE(record.reason.empty());
      CHECK_FALSE(record.hint.empty());
      CHECK(record.capabilities.empty());  // nothing of a failed plugin runs
      CHECK(record.drivers.empty());
    }
  }
  // The mismatch names both directions.
  CHECK(by_manifest(host, "mismatch.json").reason.find(
            "manifest provides capability 'org.rcand.test.mismatch_missing' but the plugin did not register it") !=
        std::string::npos);
  CHECK(by_manifest(host, "bad_manifest.json").id == "bad_manifest.json");
  CHECK_FALSE(by_manifest(host, "bad_manifest.json").manifest.has_value());
  CHECK(host.any_failed());

  // The passed-over provider was never opened.
  CHECK_FALSE(mapped("rcand_test_good_alt_provider.so"));
  CHECK_FALSE(mapped("rcand_test_good_duplicate.so"));
  CHECK(mapped("rcand_test_good.so"));
}

TEST_CASE("good serves, register ran exactly once, and a throwing plugin does not stop the others") {
  PluginHost host;
  host.scan({kFixtures});
  host.load_needed(kAllCapabilities, kAllDrivers);

  PluginRecord* good = host.find("org.rcand.test.good");
  REQUIRE(good != nullptr);
  CHECK(good->manifest_file.filename() == "good.json");  // the first of the two records with this id
  REQUIRE(good->state == PluginState::Loaded);
  REQUIRE(good->capabilities.size() == 1);
  CHECK(good->capabilities[0].info.name == "org.rcand.test.good");
  CHECK_FALSE(good->capabilities[0].info.actuates);

  auto capability = make_capability(*good, "org.rcand.test.good");
  CHECK(call_route(*capability, "/ping").body == json{{"ok", true}});
  // Libraries stay resident, so register's counter is per process: this host's registration is the latest.
  const json status = capability->status();
  CHECK(status["register_calls"] == status["registration"]);

  // Loading again opens nothing and registers nothing.
  host.load_needed(kAllCapabilities, kAllDrivers);
  CHECK(make_capability(*good, "org.rcand.test.good")->status()["register_calls"] == status["register_calls"]);

  PluginRecord* thrower = host.find("org.rcand.test.throws_in_handler");
  REQUIRE(thrower != nullptr);
  REQUIRE(thrower->state == PluginState::Loaded);
  auto throwing = make_capability(*thrower, "org.rcand.test.throws_in_handler");
  std::string failure;
  CHECK_FALSE(guarded_call(thrower->id, "GET /boom", failure, [&] { call_route(*throwing, "/boom"); }));
  CHECK(failure == "handler exploded on purpose");
  CHECK(call_route(*capability, "/ping").body == json{{"ok", true}});  // still serving

  PluginRecord* driver = host.find("org.rcand.test.driver");
  REQUIRE(driver != nullptr);
  REQUIRE(driver->drivers.size() == 1);
  CHECK(driver->drivers[0].info.protocol == "org.rcand.test.fake_drive");
  CHECK(driver->drivers[0].info.actuates);
  CHECK(driver->drivers[0].info.interface == "differential_drive");
  rcand::test::StubContext context(driver->id);
  auto made = driver->drivers[0].factory(context);
  auto* drive = dynamic_cast<rcand::sdk::DifferentialDrive*>(made.get());  // RTTI works across the boundary
  REQUIRE(drive != nullptr);
  drive->set_wheel_speeds(0.5, -0.5);
  drive->halt();
  CHECK(drive->status()["halts"] == 1);
}

TEST_CASE("a register() that never returns is given up on after the register timeout; the next plugin still loads") {
  PluginHost host;
  host.set_register_timeout(std::chrono::milliseconds(200));
  host.scan({kFixtures / "hangs_in_register", kFixtures});
  host.load_needed({"org.rcand.test.hangs_in_register", "org.rcand.test.good"}, {});
  const auto& hung = by_manifest(host, "hangs_in_register.json");
  CHECK(hung.state == PluginState::RegistrationFailed);
  CHECK(hung.reason == "register() did not return within 200 ms (runtime.plugin_start_timeout_ms)");
  CHECK(hung.capabilities.empty());
  CHECK(by_manifest(host, "good.json").state == PluginState::Loaded);
}

TEST_CASE("a plugin built for the previous ABI minor (1.0, before publish_status) loads and serves") {
  static_assert(RCAND_ABI_MINOR >= 1, "the fixture's minor 0 must be older than the kernel's");
  PluginHost host;
  host.scan({kFixtures / "older_minor"});
  host.load_needed({"org.rcand.test.older_minor"}, {});
  const auto& older = by_manifest(host, "older_minor.json");
  CHECK(to_string(older.state) == to_string(PluginState::Loaded));
  CHECK(older.reason.empty());
  auto capability = make_capability(older, "org.rcand.test.older_minor");
  CHECK(call_route(*capability, "/ping").body == json{{"ok", true}});
  CHECK(capability->status() == json::object());  // it never publishes: the status board asks status() instead
}

TEST_CASE("a plugin built for an earlier ABI minor (1.1: publish_status, before services) loads and serves") {
  static_assert(RCAND_ABI_MINOR > 1, "the fixture's minor 1 must be older than the kernel's");
  PluginHost host;
  host.scan({kFixtures / "minor_one"});
  host.load_needed({"org.rcand.test.minor_one"}, {});
  const auto& previous = by_manifest(host, "minor_one.json");
  CHECK(to_string(previous.state) == to_string(PluginState::Loaded));
  CHECK(previous.reason.empty());
  auto capability = make_capability(previous, "org.rcand.test.minor_one");
  CHECK(call_route(*capability, "/ping").body == json{{"ok", true}});
  CHECK(capability->status() == json{{"built_for", "1.1"}});
}

TEST_CASE("providers are found from manifests alone") {
  PluginHost host;
  host.scan({kFixtures});
  const auto good = host.providers_of_capability("org.rcand.test.good");
  REQUIRE(good.size() == 3);  // good, good_alt_provider, good_name_clash; never the duplicate id
  CHECK(good[0]->manifest_file.filename() == "good.json");
  CHECK(good[1]->manifest_file.filename() == "good_alt_provider.json");
  CHECK(good[2]->manifest_file.filename() == "good_name_clash.json");
  CHECK(host.providers_of_capability("org.rcand.test.nothing").empty());
  const auto drivers = host.providers_of_driver("org.rcand.test.fake_drive");
  REQUIRE(drivers.size() == 1);
  CHECK(drivers[0]->id == "org.rcand.test.driver");
  CHECK(host.providers_of_capability("org.rcand.test.fake_drive").empty());  // a driver is not a capability
  for (const auto& record : host.records()) CHECK(record->library == nullptr);  // scanning opens nothing
}

// Runs only inside a child process started by the next test, so that no earlier test has opened a library.
TEST_CASE("child: only the needed plugin is opened" * doctest::skip()) {
  if (std::getenv("RCAND_PLUGIN_HOST_CHILD") == nullptr) return;
  PluginHost host;
  host.scan({kFixtures});
  host.load_needed({"org.rcand.test.good"}, {});
  for (const auto& record : host.records()) {
    CAPTURE(record->manifest_file);
    if (record->id == "org.rcand.test.good" && record->state != PluginState::DuplicateId) {
      CHECK(record->state == PluginState::Loaded);
      continue;
    }
    if (record->manifest && record->state != PluginState::DuplicateId) {
      CHECK(record->state == PluginState::InstalledNotEnabled);
      CHECK_FALSE(record->reason.empty());
      CHECK_FALSE(record->hint.empty());
      CHECK(record->library == nullptr);
      CHECK_FALSE(mapped(record->manifest->library.filename().string()));
    }
  }
  CHECK(by_manifest(host, "throws_in_register.json").reason.find("not needed") != std::string::npos);
  CHECK(by_manifest(host, "throws_in_register.json").hint.find("capability 'org.rcand.test.throws_in_register'") !=
        std::string::npos);
  CHECK(mapped("rcand_test_good.so"));
  CHECK(host.any_failed());  // bad_manifest and the duplicate id still count as failures
  // In a fresh process register ran exactly once.
  auto capability = make_capability(*host.find("org.rcand.test.good"), "org.rcand.test.good");
  CHECK(capability->status()["register_calls"] == 1);
}

TEST_CASE("not-needed plugins stay installed-not-enabled and their libraries are not opened") {
  const std::string self = fs::read_symlink("/proc/self/exe").string();
  std::vector<std::string> args{self, "--test-case=child: only the needed plugin is opened", "--no-skip",
                                "--no-intro", "--no-version"};
  std::vector<char*> argv;
  for (auto& arg : args) argv.push_back(arg.data());
  argv.push_back(nullptr);
  std::vector<std::string> env_strings{"RCAND_PLUGIN_HOST_CHILD=1"};
  for (char** e = environ; *e != nullptr; ++e) env_strings.emplace_back(*e);
  std::vector<char*> envp;
  for (auto& entry : env_strings) envp.push_back(entry.data());
  envp.push_back(nullptr);

  pid_t pid = 0;
  REQUIRE(::posix_spawn(&pid, self.c_str(), nullptr, nullptr, argv.data(), envp.data()) == 0);
  int status = 0;
  REQUIRE(::waitpid(pid, &status, 0) == pid);
  REQUIRE(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 0);  // the child's own doctest report says what failed
}

TEST_CASE("a manifest whose library file is missing ends failed-to-open; missing paths are skipped") {
  TempDir dir{"rcand-plugins"};
  std::ofstream(dir.path() / "ghost.json") << R"({"id": "org.rcand.test.ghost", "version": "1.0.0",
    "library": "rcand_test_ghost.so", "abi": {"major": 1, "minor": 0},
    "provides": [{"kind": "capability", "name": "org.rcand.test.ghost"}]})";
  std::ofstream(dir.path() / "notes.txt") << "not a manifest";
  PluginHost host;
  host.scan({dir.path() / "does-not-exist", dir.path()});
  REQUIRE(host.records().size() == 1);
  host.load_needed({"org.rcand.test.ghost"}, {});
  const PluginRecord& ghost = *host.records()[0];
  CHECK(ghost.state == PluginState::FailedToOpen);
  CHECK(ghost.reason.find((dir.path() / "rcand_test_ghost.so").string() + " not found") != std::string::npos);
  CHECK(ghost.hint.find("rcand_test_ghost.so") != std::string::npos);
  CHECK(host.any_failed());
}

TEST_CASE("a manifest declaring another ABI major is refused without opening the library") {
  TempDir dir{"rcand-plugins"};
  // Points at a real library that would load fine; the manifest's ABI alone decides.
  fs::copy_file(kFixtures / "rcand_test_driver.so", dir.path() / "rcand_test_future.so");
  std::ofstream(dir.path() / "future.json") << R"({"id": "org.rcand.test.future", "version": "1.0.0",
    "library": "rcand_test_future.so", "abi": {"major": 2, "minor": 0},
    "provides": [{"kind": "driver", "name": "org.rcand.test.future"}]})";
  PluginHost host;
  host.scan({dir.path()});
  host.load_needed({}, {"org.rcand.test.future"});
  const PluginRecord& future = *host.records()[0];
  CHECK(future.state == PluginState::IncompatibleAbi);
  CHECK(future.reason.find("manifest declares ABI 2, kernel speaks 1") != std::string::npos);
  CHECK(future.hint == "rebuild against rcand-sdk 1.x");
  CHECK(future.library == nullptr);
  CHECK_FALSE(mapped("rcand_test_future.so"));
}

TEST_CASE("a second directory's manifest with a known id is a duplicate naming the first file") {
  TempDir dir{"rcand-plugins"};
  fs::copy_file(kFixtures / "good.json", dir.path() / "a_copy.json");
  PluginHost host;
  host.scan({kFixtures, dir.path()});
  host.scan({kFixtures});  // scanning again adds nothing
  const PluginRecord& copy = by_manifest(host, "a_copy.json");
  CHECK(copy.state == PluginState::DuplicateId);
  CHECK(copy.hint.find((kFixtures / "good.json").string()) != std::string::npos);
  CHECK(host.records().size() == 15);
}

TEST_CASE("format_table and to_json list every plugin with its state") {
  PluginHost host;
  host.scan({kFixtures});
  host.load_needed(kAllCapabilities, kAllDrivers);
  const std::string table = host.format_table();
  std::istringstream lines(table);
  std::string header;
  std::getline(lines, header);
  CHECK(header.find("ID") == 0);
  const auto state_column = header.find("STATE");
  REQUIRE(state_column != std::string::npos);
  CHECK(header.find("REASON / HINT") != std::string::npos);
  for (const auto& record : host.records()) {
    CAPTURE(record->id);
    bool found = false;
    std::istringstream all(table);
    for (std::string line; std::getline(all, line);)
      if (line.rfind(record->id + " ", 0) == 0 &&
          line.compare(state_column, to_string(record->state).size(), to_string(record->state)) == 0)
        found = true;  // the state sits in its aligned column
    CHECK(found);
  }

  const json doc = host.to_json();
  REQUIRE(doc.size() == host.records().size());
  const auto good = std::find_if(doc.begin(), doc.end(), [](const json& p) { return p["id"] == "org.rcand.test.good"; });
  REQUIRE(good != doc.end());
  CHECK((*good)["state"] == "loaded");
  CHECK((*good)["version"] == "1.2.3");
  CHECK((*good)["provides"] == json::parse(R"([{"kind": "capability", "name": "org.rcand.test.good", "actuates": false}])"));
  CHECK((*good)["manifest"] == (kFixtures / "good.json").string());
  for (const auto& entry : doc)
    for (const char* key : {"id", "version", "state", "reason", "hint", "provides", "manifest"}) CHECK(entry.contains(key));
}

TEST_CASE("state names") {
  using rcand::kernel::is_failure;
  CHECK(to_string(PluginState::InstalledNotEnabled) == "installed-not-enabled");
  CHECK(to_string(PluginState::FailedToOpen) == "failed-to-open");
  CHECK(to_string(PluginState::IncompatibleAbi) == "incompatible-abi");
  CHECK(to_string(PluginState::ManifestMismatch) == "manifest-mismatch");
  CHECK(to_string(PluginState::RegistrationFailed) == "registration-failed");
  CHECK(to_string(PluginState::DuplicateId) == "duplicate-id");
  CHECK(to_string(PluginState::InvalidManifest) == "invalid-manifest");
  CHECK(to_string(PluginState::Failed) == "failed");
  CHECK(to_string(PluginState::Loaded) == "loaded");
  CHECK_FALSE(is_failure(PluginState::Loaded));
  CHECK_FALSE(is_failure(PluginState::InstalledNotEnabled));
  CHECK(is_failure(PluginState::DuplicateId));
  CHECK(is_failure(PluginState::Failed));
}
