// Built as a plugin for ABI 1.1 would have been: its descriptor says minor 1, it uses what 1.1 added
// (PluginContext::publish_status) and never what 1.2 added (service(), offer_service(), stream_routes()). A kernel
// of a newer minor must still load it, serve its routes and show what it published.
#include "../fixture.hpp"

namespace {

class MinorOne final : public rcand::sdk::Capability {
 public:
  explicit MinorOne(rcand::sdk::PluginContext& ctx) : ctx_(ctx) {}
  void start() override { ctx_.publish_status({{"built_for", "1.1"}}); }
  std::vector<rcand::sdk::Route> routes() override {
    return {rcand::test::get_route("/ping", [](const rcand::sdk::Request&) { return rcand::sdk::Response::ok({{"ok", true}}); })};
  }
  rcand::sdk::Json status() const override { return {{"built_for", "1.1"}}; }

 private:
  rcand::sdk::PluginContext& ctx_;
};

void register_minor_one(rcand_registrar* registrar) {
  reinterpret_cast<rcand::sdk::Registrar*>(registrar)->add_capability(
      {"org.rcand.test.minor_one", false}, [](rcand::sdk::PluginContext& ctx) { return std::make_unique<MinorOne>(ctx); });
}

}  // namespace

extern "C" RCAND_EXPORT const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void) {
  static_assert(RCAND_ABI_MINOR > 1, "this fixture stands for the minor before the kernel's");
  static const rcand_plugin_descriptor descriptor{sizeof(rcand_plugin_descriptor),
                                                  RCAND_DESCRIPTOR_MAGIC,
                                                  RCAND_ABI_MAJOR,
                                                  1,
                                                  "org.rcand.test.minor_one",
                                                  "1.0.0",
                                                  "fixture",
                                                  register_minor_one};
  return &descriptor;
}
