// The plugin reload fixture (kernel/plugins PluginRuntime::reload, rcanctl plugins reload): built twice from this
// file, as version 1.0.0 and 2.0.0 (RELOAD_FIXTURE_VERSION), capability org.rcand.test.reload:
//   GET /api/cap/org.rcand.test.reload/version -> {"version": "<built version>"}
//   GET /api/cap/org.rcand.test.reload/hold?entered=FILE&release=FILE -> creates `entered`, then answers
//       {"version", "released": true} once `release` exists (false after 5 s): an in-flight call a test controls.
//   GET /api/cap/org.rcand.test.reload/added -> {"added": true}, in version 2.0.0 only (RELOAD_FIXTURE_NEW_ROUTE).
#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "../fixture.hpp"

namespace {

rcand::sdk::Response hold(const rcand::sdk::Request& request) {
  const auto entered = request.query.find("entered");
  const auto release = request.query.find("release");
  if (entered == request.query.end() || release == request.query.end())
    return rcand::sdk::Response::error(400, "BAD_REQUEST", "entered and release are required");
  std::ofstream(entered->second) << "entered\n";
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  bool released = false;
  while (!(released = std::filesystem::exists(release->second)) && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));  // the test's file is the event; nothing else to wait on
  return rcand::sdk::Response::ok({{"version", RELOAD_FIXTURE_VERSION}, {"released", released}});
}

void register_reload(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"org.rcand.test.reload", false}, [](rcand::sdk::PluginContext&) {
    return std::make_unique<rcand::test::FixedRoutesCapability>(
        std::vector<rcand::sdk::Route>{
            rcand::test::get_route("/version",
                                   [](const rcand::sdk::Request&) {
                                     return rcand::sdk::Response::ok({{"version", RELOAD_FIXTURE_VERSION}});
                                   }),
            rcand::test::get_route("/hold", hold),
#ifdef RELOAD_FIXTURE_NEW_ROUTE  // version 2 only: a route the first version did not have
            rcand::test::get_route("/added",
                                   [](const rcand::sdk::Request&) {
                                     return rcand::sdk::Response::ok({{"added", true}});
                                   }),
#endif
        },
        rcand::sdk::Json{{"version", RELOAD_FIXTURE_VERSION}});
  });
}

}  // namespace

RCAND_PLUGIN("org.rcand.test.reload", RELOAD_FIXTURE_VERSION, register_reload)
