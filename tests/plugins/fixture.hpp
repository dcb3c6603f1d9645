// Shared by the fixture plugins: a capability that serves a fixed list of routes.
#pragma once

// export.hpp first: sdk/capability.hpp uses RCAND_INTERFACE without including it.
#include <rcand/sdk/export.hpp>
#include <rcand/sdk/plugin.hpp>

#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace rcand::test {

class FixedRoutesCapability final : public sdk::Capability {
 public:
  FixedRoutesCapability(std::vector<sdk::Route> routes, sdk::Json status) : routes_(std::move(routes)), status_(std::move(status)) {}
  std::vector<sdk::Route> routes() override { return routes_; }
  sdk::Json status() const override { return status_; }

 private:
  std::vector<sdk::Route> routes_;
  sdk::Json status_;
};

inline sdk::Route get_route(std::string path, std::function<sdk::Response(const sdk::Request&)> handler) {
  sdk::Route route;
  route.method = "GET";
  route.path = std::move(path);
  route.handler = std::move(handler);
  return route;
}

// Registers capability `name` whose instances serve GET <prefix>/ping -> {"ok": true}.
inline void add_ping_capability(sdk::Registrar& registrar, std::string name) {
  registrar.add_capability({std::move(name), false}, [](sdk::PluginContext&) {
    return std::make_unique<FixedRoutesCapability>(
        std::vector<sdk::Route>{get_route("/ping", [](const sdk::Request&) { return sdk::Response::ok({{"ok", true}}); })},
        sdk::Json::object());
  });
}

}  // namespace rcand::test
