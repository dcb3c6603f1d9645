// com.acme.gripper on the SDK's fake host: grip, open, state, bad input, e-stop refusal.
#include <doctest/doctest.h>

#include <rcand/sdk/testing/fake_host.hpp>

#include <fstream>
#include <limits>

#include "gripper_capability.hpp"
#include "sim_gripper.hpp"

extern "C" const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void);

using nlohmann::json;
using rcand::sdk::Role;
using rcand::sdk::testing::FakeHost;

namespace {

json manifest() {
  std::ifstream in(RCAND_PLUGIN_MANIFEST);  // the manifest's path, from the build (rcand_add_plugin_test in a vendor's)
  REQUIRE(in.good());
  return json::parse(in);
}

struct Fixture {
  FakeHost host;
  explicit Fixture(json driver_settings = json::object()) {
    host.load(RCAND_ENTRY_FUNCTION, manifest());  // also checks provides == registration
    host.add_driver("gripper", "acme_gripper_sim", std::move(driver_settings));
    host.add_capability("com.acme.gripper");
  }
  acme::gripper::SimGripper& sim() { return host.driver<acme::gripper::SimGripper>("gripper"); }
  rcand::sdk::Response grip(json body, Role role = Role::User) {
    return host.call("POST", "/api/cap/com.acme.gripper/grip", std::move(body), role);
  }
  rcand::sdk::Response state(Role role = Role::User) { return host.call("GET", "/api/cap/com.acme.gripper/state", {}, role); }
};

}  // namespace

TEST_CASE("close, open and a set opening move the gripper and are reported by /state") {
  Fixture f;
  auto r = f.state();
  REQUIRE(r.status == 200);
  CHECK(r.body == json{{"opening", 1.0}, {"holding", false}, {"actuator", "gripper"}});

  r = f.grip({{"state", "close"}});
  REQUIRE(r.status == 200);
  CHECK(r.body["ok"] == true);
  CHECK(r.body["opening"] == 0.0);
  CHECK(r.body["holding"] == false);
  CHECK(f.sim().opening() == 0.0);

  r = f.grip({{"opening", 0.6}});
  CHECK(r.body["opening"] == 0.6);
  CHECK(f.state().body["opening"] == 0.6);

  r = f.grip({{"state", "open"}});
  CHECK(r.body["opening"] == 1.0);
  CHECK(f.sim().status()["commands"] == 3);
}

TEST_CASE("closing on an object holds it") {
  Fixture f({{"object_size", 0.3}});
  const auto r = f.grip({{"state", "close"}});
  CHECK(r.body["opening"] == 0.3);
  CHECK(r.body["holding"] == true);
  CHECK(f.state().body["holding"] == true);
  CHECK(f.grip({{"state", "open"}}).body["holding"] == false);
}

TEST_CASE("bad input answers 400 naming the field; the gripper is not commanded") {
  Fixture f;
  const std::vector<std::pair<json, std::string>> cases = {
      {json::object(), "state"},
      {{{"state", "half"}}, "state"},
      {{{"state", 1}}, "state"},
      {{{"opening", 1.5}}, "opening"},
      {{{"opening", -0.1}}, "opening"},
      {{{"opening", "wide"}}, "opening"},
      {{{"opening", std::numeric_limits<double>::quiet_NaN()}}, "opening"},
      {{{"state", "open"}, {"opening", 0.5}}, "opening"},
      {json::array({1, 2}), "body"},
  };
  for (const auto& entry : cases) {
    // Named references, not structured bindings: CAPTURE makes a lambda, and clang 14 cannot capture a binding.
    const auto& body = std::get<0>(entry); const auto& field = std::get<1>(entry);
    CAPTURE(body.dump());
    const auto r = f.grip(body);
    CHECK(r.status == 400);
    CHECK(r.body["code"] == "BAD_REQUEST");
    CHECK(r.body["field"] == field);
  }
  CHECK(f.grip({{"state", "half"}}).body["allowed"] == json::array({"open", "close"}));
  CHECK(f.sim().status()["commands"] == 0);
}

TEST_CASE("e-stop: /grip answers 423 and the gripper receives nothing; /state serves the last known state") {
  Fixture f;
  REQUIRE(f.grip({{"opening", 0.4}}).status == 200);
  f.host.latch_estop("test");
  CHECK(f.sim().status()["halts"] == 1);
  const auto r = f.grip({{"state", "close"}});
  CHECK(r.status == 423);
  CHECK(r.body["code"] == "ESTOP_ACTIVE");
  CHECK(f.sim().opening() == 0.4);
  CHECK(f.sim().status()["commands"] == 1);
  const auto s = f.state();
  CHECK(s.status == 200);
  CHECK(s.body["opening"] == 0.4);
  f.host.clear_estop();
  CHECK(f.grip({{"state", "close"}}).status == 200);
}

TEST_CASE("routes need scope control; unknown subpaths are 404; no gripper is 503") {
  Fixture f;
  CHECK(f.state(Role::Guest).status == 403);
  CHECK(f.grip({{"state", "close"}}, Role::Guest).status == 403);
  CHECK(f.host.call("GET", "/api/cap/com.acme.gripper/nothing").status == 404);

  FakeHost bare;
  bare.load(RCAND_ENTRY_FUNCTION, manifest());
  bare.add_capability("com.acme.gripper");
  CHECK(bare.call("GET", "/api/cap/com.acme.gripper/state").status == 503);
  CHECK(bare.call("POST", "/api/cap/com.acme.gripper/grip", {{"state", "open"}}).body["code"] == "UNAVAILABLE");
}

TEST_CASE("the capability publishes its status after each change, and only then") {
  Fixture f;
  auto& gripper = f.host.capability<acme::gripper::GripperCapability>("com.acme.gripper");
  CHECK_FALSE(f.host.last_published_status("com.acme.gripper"));
  REQUIRE(f.state().status == 200);  // first read of the gripper: the cached state changes from unknown to open
  CHECK(*f.host.last_published_status("com.acme.gripper") == json{{"opening", 1.0}, {"holding", false}});
  REQUIRE(f.state().status == 200);  // nothing changed: nothing published
  CHECK(f.host.published_statuses("com.acme.gripper").size() == 1);

  REQUIRE(f.grip({{"state", "close"}}).status == 200);
  CHECK(*f.host.last_published_status("com.acme.gripper") == gripper.status());
  CHECK(gripper.status() == json{{"opening", 0.0}, {"holding", false}});
  REQUIRE(f.grip({{"state", "close"}}).status == 200);  // already closed
  CHECK(f.host.published_statuses("com.acme.gripper").size() == 2);
  REQUIRE(f.grip({{"opening", 0.5}}).status == 200);
  CHECK(f.host.published_statuses("com.acme.gripper").size() == 3);
  CHECK((*f.host.last_published_status("com.acme.gripper"))["opening"] == 0.5);
}
