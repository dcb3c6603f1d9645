// Offers the Greeter service (greeter.hpp) from its capability's start(), then offers it a second time, which must be
// refused. GET /offers says what both offers returned.
#include "../fixture.hpp"
#include "greeter.hpp"

namespace {

class Offerer final : public rcand::sdk::Capability, public rcand::test::Greeter {
 public:
  explicit Offerer(rcand::sdk::PluginContext& ctx) : ctx_(ctx) {}
  void start() override {
    first_ = rcand::sdk::offer<rcand::test::Greeter>(ctx_, *this);
    second_ = rcand::sdk::offer<rcand::test::Greeter>(ctx_, *this);  // one provider per service: refused
  }
  std::vector<rcand::sdk::Route> routes() override {
    return {rcand::test::get_route("/offers", [this](const rcand::sdk::Request&) {
      return rcand::sdk::Response::ok({{"first", first_}, {"second", second_}});
    })};
  }
  const char* greeting() const noexcept override { return "hello from service_offer"; }

 private:
  rcand::sdk::PluginContext& ctx_;
  bool first_ = false, second_ = false;
};

void register_offer(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"org.rcand.test.service_offer", false},
                           [](rcand::sdk::PluginContext& ctx) { return std::make_unique<Offerer>(ctx); });
}

}  // namespace

RCAND_PLUGIN("org.rcand.test.service_offer", "1.0.0", register_offer)
