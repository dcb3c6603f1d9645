// Loads fine; GET /api/cap/org.rcand.test.throws_in_handler/boom throws from its handler (the caller must get
// 500 INTERNAL each time, the capability stays in service with the throws counted, and the others keep serving).
#include <stdexcept>

#include "fixture.hpp"

namespace {
void register_handler_throws(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"org.rcand.test.throws_in_handler", false}, [](rcand::sdk::PluginContext&) {
    return std::make_unique<rcand::test::FixedRoutesCapability>(
        std::vector<rcand::sdk::Route>{rcand::test::get_route(
            "/boom", [](const rcand::sdk::Request&) -> rcand::sdk::Response {
              throw std::runtime_error("handler exploded on purpose");
            })},
        rcand::sdk::Json::object());
  });
}
}  // namespace

RCAND_PLUGIN("org.rcand.test.throws_in_handler", "1.0.0", register_handler_throws)
