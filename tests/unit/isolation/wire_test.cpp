#include "libs/isolation/wire.hpp"

#include <doctest/doctest.h>

#include "libs/base/steady_clock.hpp"
#include "libs/isolation/actuator_calls.hpp"
#include "rcand/sdk/interfaces/arm.hpp"
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
  CHECK_FALSE(isolation::reading_for("joint_states")(drive));  // a drive is no arm: WrongInterface, as in process
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

TEST_CASE(
    "actuator calls: a joint arm's targets and states cross whole, an unknown position stays unknown, and a bad "
    "target list is refused before any gate") {
  struct Arm final : sdk::ActuatorDriver, sdk::JointArm {
    std::string_view interface_name() const noexcept override { return sdk::JointArm::kInterface; }
    void halt() noexcept override {}
    void set_joint_targets(const std::vector<sdk::JointTarget>& targets) override { given = targets; }
    std::vector<sdk::JointState> joint_states() const override {
      return {{"shoulder", 12.5, 30, 60, true, true}, {"elbow", std::nullopt, 0, 0, false, false}};
    }
    std::vector<sdk::JointTarget> given;
  } arm;
  // The stand-in's calls carried out on `arm` as rcand would (command_for / reading_for), not through a gate.
  auto outcome = std::make_shared<isolation::CallOutcome>();
  const isolation::CallSender to_rcand = [&](std::string_view op, std::string_view method, json args) {
    if (op == "actuate") return json{{"gate", isolation::command_for(method, args)(arm) ? 0 : 3}};
    return json{{"gate", 0}, {"result", *isolation::reading_for(method)(arm)}};
  };
  auto actuating = isolation::remote_actuator(sdk::JointArm::kInterface, "actuate", to_rcand, outcome);
  REQUIRE(actuating);
  CHECK(actuating->interface_name() == "joint_arm");
  auto* remote = dynamic_cast<sdk::JointArm*>(actuating.get());  // actuate_as<JointArm> cross-casts the same way
  REQUIRE(remote != nullptr);
  remote->set_joint_targets({{"shoulder", 30, 45}, {"elbow", 90, 0}});
  REQUIRE(arm.given.size() == 2);
  CHECK(arm.given[1].joint == "elbow");
  CHECK(arm.given[1].position_deg == 90);
  CHECK(arm.given[0].velocity_dps == 45);

  auto reading = isolation::remote_actuator(sdk::JointArm::kInterface, "inspect", to_rcand, outcome);
  const auto states = dynamic_cast<const sdk::JointArm&>(*reading).joint_states();
  REQUIRE(states.size() == 2);
  CHECK(states[0].position_deg == 12.5);
  CHECK(states[0].moving);
  CHECK_FALSE(states[1].position_deg.has_value());  // a failed read is never a made-up 0.0
  CHECK(outcome->status == sdk::GateStatus::Ok);

  CHECK_THROWS_AS(isolation::command_for("set_joint_targets", json::array({{"shoulder", "far", 1}})), isolation::CallError);
  CHECK_THROWS_AS(isolation::command_for("set_joint_targets", json{{"shoulder", 30}}), isolation::CallError);
  SteadyClock clock;
  sdk::testing::RecordingDrive drive(clock);
  CHECK_FALSE(isolation::command_for("set_joint_targets", json::array({{"shoulder", 30, 10}}))(drive));  // WrongInterface
}
