// Finds the Greeter service another plugin offers, at each request (so the order in which the two start does not
// matter). GET /greet answers {"found", "greeting"}.
#include "../fixture.hpp"
#include "greeter.hpp"

namespace {

void register_find(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"org.rcand.test.service_find", false}, [](rcand::sdk::PluginContext& ctx) {
    return std::make_unique<rcand::test::FixedRoutesCapability>(
        std::vector<rcand::sdk::Route>{rcand::test::get_route(
            "/greet",
            [&ctx](const rcand::sdk::Request&) {
              const auto* greeter = rcand::sdk::find<rcand::test::Greeter>(ctx);
              return rcand::sdk::Response::ok({{"found", greeter != nullptr}, {"greeting", greeter ? greeter->greeting() : ""}});
            })},
        rcand::sdk::Json::object());
  });
}

}  // namespace

RCAND_PLUGIN("org.rcand.test.service_find", "1.0.0", register_find)
