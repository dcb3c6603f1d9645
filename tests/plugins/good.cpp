// Loads fine: capability org.rcand.test.good, GET /api/cap/org.rcand.test.good/ping -> {"ok": true}.
// Its status() reports how often register ran in this process ("register_calls") and which call made the
// factory ("registration"), so a test can check the kernel called it exactly once.
#include <atomic>

#include "fixture.hpp"

namespace {
std::atomic<int> register_calls{0};

void register_good(rcand::sdk::Registrar& registrar) {
  const int registration = ++register_calls;
  registrar.add_capability({"org.rcand.test.good", false}, [registration](rcand::sdk::PluginContext&) {
    return std::make_unique<rcand::test::FixedRoutesCapability>(
        std::vector<rcand::sdk::Route>{rcand::test::get_route(
            "/ping", [](const rcand::sdk::Request&) { return rcand::sdk::Response::ok({{"ok", true}}); })},
        rcand::sdk::Json{{"register_calls", register_calls.load()}, {"registration", registration}});
  });
}
}  // namespace

RCAND_PLUGIN("org.rcand.test.good", "1.2.3", register_good)
