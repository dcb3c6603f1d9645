// Services between plugins through a real kernel (issue 14 item 4): one fixture plugin offers a service of its own
// interface, another finds it at request time; the offers end with the instances; and plugins built for the minors
// before 1.2 (0 and 1) load next to them and serve.
#include <doctest/doctest.h>
#include <rcand/sdk/abi.h>

#include <rcand/sdk/testing/manual_clock.hpp>

#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <optional>

#include "../../plugins/services/greeter.hpp"
#include "kernel/api/api.hpp"
#include "kernel/kernel.hpp"
#include "kernel/plugins/instance_context.hpp"
#include "kernel/plugins/plugin_runtime.hpp"
#include "kernel/safety/estop.hpp"
#include "kernel/safety/kernel_motion_gate.hpp"
#include "libs/rcan/crypto.hpp"

using namespace rcand;
using namespace rcand::kernel;
using nlohmann::json;

namespace {

namespace fs = std::filesystem;
const fs::path kServiceFixtures = RCAND_TEST_PLUGIN_DIR;
const std::string kOwnerToken = "service-lookup-test-owner-token";

config::RobotConfig services_robot() {
  const std::string yaml = R"(rcan_version: "1.3"
metadata: {robot_name: sally, robot_uuid: "7a1b2c3d", manufacturer: rcand, model: fixture}
rcan_protocol:
  port: 8000
  enable_mdns: false
  enable_jwt: false
  capabilities: [status, org.rcand.test.service_find, org.rcand.test.service_offer, org.rcand.test.older_minor,
                 org.rcand.test.minor_one]
runtime:
  listen: {address: 127.0.0.1, port: 0}
  plugin_paths: [")" + (kServiceFixtures / "services").string() +
                           R"(", ")" + (kServiceFixtures / "older_minor").string() + R"(", ")" +
                           (kServiceFixtures / "minor_one").string() +
                           R"("]
  swarm_file: /nonexistent/swarm.yaml
  auth:
    tokens:
      - {principal: owner, role: owner, sha256: )" +
                           sha256_hex(kOwnerToken) + "}\n";
  return config::parse_robot_config(yaml, "sally.rcan.yaml", "/").config;
}

// The Api's answer to an owner's GET (capability handlers answer from their worker).
json get(Api& api, const std::string& path) {
  http::Request request;
  request.method = "GET";
  request.target = request.path = path;
  request.headers["authorization"] = "Bearer " + kOwnerToken;
  request.remote = "127.0.0.1:1";
  std::mutex mutex;
  std::condition_variable cv;
  std::optional<http::Response> answer;
  api.handle(std::move(request), [&](http::Response response) {
    std::lock_guard lock(mutex);
    answer = std::move(response);
    cv.notify_all();
  });
  std::unique_lock lock(mutex);
  REQUIRE(cv.wait_for(lock, std::chrono::seconds(10), [&] { return answer.has_value(); }));
  INFO(path << " -> " << answer->status << " " << answer->body);
  REQUIRE(answer->status == 200);
  return json::parse(answer->body);
}

}  // namespace

TEST_CASE("a real kernel: one plugin finds the service another offers; ABI 1.0 and 1.1 plugins load beside them") {
  static_assert(RCAND_ABI_MINOR > 1, "minor_one and older_minor stand for minors before this one");
  Kernel kernel(services_robot(), embedded_kernel_options());
  for (const auto& record : kernel.plugins().records()) {
    CAPTURE(record->id);
    CHECK(to_string(record->state) == to_string(PluginState::Loaded));
  }
  Api& api = kernel.api();
  // Whichever of the two started first, the finder finds it: the lookup happens at use time.
  const json greeting = get(api, "/api/cap/org.rcand.test.service_find/greet");
  CHECK(greeting == json{{"found", true}, {"greeting", "hello from service_offer"}});
  CHECK(get(api, "/api/cap/org.rcand.test.service_offer/offers") == json{{"first", true}, {"second", false}});

  CHECK(get(api, "/api/cap/org.rcand.test.older_minor/ping") == json{{"ok", true}});
  CHECK(get(api, "/api/cap/org.rcand.test.minor_one/ping") == json{{"ok", true}});
  const json status = get(api, "/api/status");
  CHECK(status["capabilities"]["org.rcand.test.minor_one"]["status"] == json{{"built_for", "1.1"}});
  CHECK(status["capabilities"]["org.rcand.test.older_minor"]["state"] == "ok");
  CHECK(status["nav_running"] == false);  // no nav, so no PoseSource
  CHECK_FALSE(status.contains("pose"));
}

TEST_CASE("the plugin runtime withdraws an instance's offers before its shutdown(); a finder then gets null") {
  PluginHost host;
  host.scan({kServiceFixtures / "services"});
  host.load_needed({"org.rcand.test.service_offer", "org.rcand.test.service_find"}, {});
  sdk::testing::ManualClock clock;
  ActuatorTable actuators;
  Estop estop{clock, actuators};
  KernelMotionGate gate{actuators, estop};
  sdk::ConfigView robot_config;
  KernelServices services{clock, estop, gate, robot_config, nullptr, "rcan://test/robot", {}};
  PluginRuntime runtime(host, services, actuators);
  runtime.start_capabilities({"org.rcand.test.service_offer", "org.rcand.test.service_find"}, config::RobotConfig{});

  const auto* greeter = sdk::find<test::Greeter>(services.directory);  // the kernel side finds it with the same header
  REQUIRE(greeter != nullptr);
  CHECK(std::string(greeter->greeting()) == "hello from service_offer");
  auto* finder = runtime.capability("org.rcand.test.service_find");
  REQUIRE(finder != nullptr);
  REQUIRE(finder->routes.size() == 1);
  CHECK(finder->routes[0].handler(sdk::Request{}).body["found"] == true);

  runtime.shutdown();
  CHECK(sdk::find<test::Greeter>(services.directory) == nullptr);
  CHECK(finder->routes[0].handler(sdk::Request{}).body["found"] == false);  // objects live on until destroyed
}
