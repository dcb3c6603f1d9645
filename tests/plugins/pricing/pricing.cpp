// A vendor's bid price through R2rLink::set_cost_function (SDK 1.0, kept for ABI 1): 12.5 s for every task. Set in
// the constructor, before the fleet plugin (declared after it) has started: rcand hands the price on when R2R starts.
#include "../fixture.hpp"

namespace {

void register_pricing(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"org.rcand.test.pricing", false}, [](rcand::sdk::PluginContext& ctx) {
    if (rcand::sdk::R2rLink* link = ctx.r2r())
      link->set_cost_function([](const rcand::sdk::Json&, const std::optional<rcand::sdk::R2rPose>&, std::size_t) {
        return std::optional<double>(12.5);
      });
    return std::make_unique<rcand::test::FixedRoutesCapability>(std::vector<rcand::sdk::Route>{}, rcand::sdk::Json::object());
  });
}

}  // namespace

RCAND_PLUGIN("org.rcand.test.pricing", "1.0.0", register_pricing)
