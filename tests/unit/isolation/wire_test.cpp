#include "libs/isolation/wire.hpp"

#include <doctest/doctest.h>

#include "libs/base/steady_clock.hpp"
#include "libs/isolation/actuator_calls.hpp"
#include "rcand/sdk/testing/recording_drive.hpp"

using namespace rcand;
using nlohmann::json;

TEST_CASE("wire: a route crosses without its handler, every other field kept") {
  sdk::Route route;
  route.method = "POST";
  route.path = "/grip";
  route.scope = sdk::Scope::Config;
  route.motion = true;
  route.action_type = "grip";
  route.handler = [](const sdk::Request&) { return sdk::Response::ok(); };
  const auto back = isolation::decode_route(json::from_msgpack(json::to_msgpack(isolation::encode_route(route))));
  CHECK(back.method == "POST");
  CHECK(back.path == "/grip");
  CHECK(back.scope == sdk::Scope::Config);
  CHECK(back.motion);
  CHECK(back.action_type == "grip");
  CHECK_FALSE(back.handler);
}

TEST_CASE("wire: a request crosses whole, except its credential, which never leaves rcand") {
  sdk::Request request;
  request.method = "POST";
  request.path = "/api/cap/com.acme.gripper/grip";
  request.subpath = "/grip";
  request.query = {{"force", "0.5"}, {"mode", "soft"}};
  request.body = {{"width", 0.04}, {"tags", {"a", "b"}}};
  request.principal = "ops";
  request.role = sdk::Role::Owner;
  request.message_id = "m-1";
  request.scopes = {sdk::Scope::Status, sdk::Scope::Control};
  request.credential = std::make_shared<sdk::Credential>();
  const auto back = isolation::decode_request(json::from_msgpack(json::to_msgpack(isolation::encode_request(request))));
  CHECK(back.method == request.method);
  CHECK(back.path == request.path);
  CHECK(back.subpath == request.subpath);
  CHECK(back.query == request.query);
  CHECK(back.body == request.body);
  CHECK(back.principal == "ops");
  CHECK(back.role == sdk::Role::Owner);
  CHECK(back.message_id == "m-1");
  CHECK(back.scopes == request.scopes);
  CHECK(back.credential == nullptr);
}

TEST_CASE("wire: a request that does not decode throws, and nothing of it is used") {
  CHECK_THROWS(isolation::decode_request(json::array({"GET"})));
  CHECK_THROWS(isolation::decode_route(json{{"method", "GET"}}));
}

TEST_CASE("actuator calls: a drive's calls reach the driver; a call no actuator takes is refused before any gate") {
  SteadyClock clock;
  sdk::testing::RecordingDrive drive(clock);
  CHECK(isolation::command_for("set_wheel_speeds", json::array({0.25, -0.5}))(drive));
  CHECK(drive.left() == 0.25);
  CHECK(drive.right() == -0.5);
  CHECK_THROWS_WITH_AS(isolation::command_for("set_wheel_speeds", json::array({"fast", 1})),
                       "set_wheel_speeds: argument 0 must be a number", isolation::CallError);
  CHECK_THROWS_WITH_AS(isolation::command_for("set_wheel_speeds", json{{"left", 1}}),
                       "set_wheel_speeds: argument 0 must be a number", isolation::CallError);
  CHECK_THROWS_WITH_AS(isolation::command_for("fly", json::array()),
                       "no actuator interface an isolated capability can call has a method 'fly'", isolation::CallError);
  CHECK(isolation::command_for("halt", json::array())(drive));
  CHECK_FALSE(drive.moving());
  CHECK(isolation::reading_for("status")(drive) == json::object());
  CHECK_THROWS_AS(isolation::reading_for("secrets"), isolation::CallError);
}

TEST_CASE("actuator calls: a drive's call on an actuator of another interface moves nothing and says so") {
  class Gripper final : public sdk::ActuatorDriver {
   public:
    std::string_view interface_name() const noexcept override { return "gripper"; }
    void halt() noexcept override { ++halts; }
    int halts = 0;
  } gripper;
  CHECK_FALSE(isolation::command_for("set_wheel_speeds", json::array({0.1, 0.1}))(gripper));
  CHECK(isolation::command_for("halt", json::array())(gripper));  // every actuator halts
  CHECK(gripper.halts == 1);
}

TEST_CASE("actuator calls: a stand-in sends its calls and stops calling once one was refused") {
  std::vector<json> sent;
  auto outcome = std::make_shared<isolation::CallOutcome>();
  int answers = 0;
  auto drive = isolation::remote_actuator(
      sdk::DifferentialDrive::kInterface, "actuate",
      [&](std::string_view op, std::string_view method, json args) {
        sent.push_back({op, method, args});
        // The first call is carried out, the second refused: the e-stop latched between them.
        return json{{"gate", static_cast<int>(++answers == 1 ? sdk::GateStatus::Ok : sdk::GateStatus::EstopActive)}};
      },
      outcome);
  REQUIRE(drive);
  auto& typed = dynamic_cast<sdk::DifferentialDrive&>(*drive);
  typed.set_wheel_speeds(0.5, 0.5);
  CHECK(outcome->status == sdk::GateStatus::Ok);
  typed.set_wheel_speeds(1.0, 1.0);
  CHECK(outcome->status == sdk::GateStatus::EstopActive);
  typed.set_wheel_speeds(0.7, 0.7);  // never sent: refused once, the command moves nothing more
  REQUIRE(sent.size() == 2);
  CHECK(sent[0] == json::array({"actuate", "set_wheel_speeds", {0.5, 0.5}}));
  CHECK_FALSE(isolation::remote_actuator("gripper", "actuate", {}, outcome));  // not carried yet: no stand-in
}

TEST_CASE("actuator calls: a driver's own error reaches the plugin as a throw") {
  auto outcome = std::make_shared<isolation::CallOutcome>();
  auto drive = isolation::remote_actuator(
      sdk::DifferentialDrive::kInterface, "actuate",
      [](std::string_view, std::string_view, json) {
        return json{{"gate", static_cast<int>(sdk::GateStatus::ActuatorFailed)}, {"error", "serial port gone"}};
      },
      outcome);
  CHECK_THROWS_WITH(dynamic_cast<sdk::DifferentialDrive&>(*drive).set_wheel_speeds(0.1, 0.1), "serial port gone");
  CHECK(outcome->status == sdk::GateStatus::ActuatorFailed);
}
