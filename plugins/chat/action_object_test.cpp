// The action object chat answers as `action`: one type per kind of request chat can dispatch (docs/protocol.md §7.5).
#include <doctest/doctest.h>

#include "action_object.hpp"

using nlohmann::json;
using rcand::plugins::chat::action_object;

namespace {

json request(const char* method, const char* path, json body = nullptr) {
  json r{{"method", method}, {"path", path}};
  if (!body.is_null()) r["body"] = std::move(body);
  return r;
}

}  // namespace

TEST_CASE("an /api/action body is its own action object; rcand's routes map to a type of their own") {
  const json move{{"type", "move"}, {"linear", 0.5}, {"angular", 0.0}, {"duration_ms", 1000}};
  CHECK(action_object(request("POST", "/api/action", move)) == move);
  CHECK(action_object(request("POST", "/api/action", {{"type", "stop"}})) == json{{"type", "stop"}});
  const json pose{{"type", "arm_pose"}, {"pose", "home"}};
  CHECK(action_object(request("POST", "/api/action", pose)) == pose);
  CHECK(action_object(request("POST", "/api/stop", {{"reason", "chat"}})) == json{{"type", "estop"}, {"reason", "chat"}});
  CHECK(action_object(request("POST", "/api/nav/waypoint", {{"distance_m", 1.0}, {"heading_deg", 90.0}, {"speed", 0.5}})) ==
        json{{"type", "nav_waypoint"}, {"distance_m", 1.0}, {"heading_deg", 90.0}, {"speed", 0.5}});
  CHECK(action_object(request("POST", "/api/nav/cancel", json::object())) == json{{"type", "nav_cancel"}});
  CHECK(action_object(request("GET", "/api/nav/status")) == json{{"type", "nav_status"}});
  CHECK(action_object(request("GET", "/api/status")) == json{{"type", "status"}});
  CHECK(action_object(request("GET", "/api/depth/obstacles")) == json{{"type", "obstacles"}});
  CHECK(action_object(request("GET", "/api/stream/snapshot")) == json{{"type", "snapshot"}});
}

TEST_CASE("a body never renames the type; custom capabilities and other requests keep what was asked") {
  CHECK(action_object(request("POST", "/api/nav/waypoint", {{"type", "move"}, {"distance_m", 1.0}})) ==
        json{{"type", "nav_waypoint"}, {"distance_m", 1.0}});
  CHECK(action_object(request("POST", "/api/cap/com.acme.gripper/grip", {{"state", "open"}})) ==
        json{{"type", "custom"},
             {"capability", "com.acme.gripper"},
             {"route", "/grip"},
             {"method", "POST"},
             {"body", {{"state", "open"}}}});
  CHECK(action_object(request("POST", "/api/config/reload", json::object())) ==
        json{{"type", "request"}, {"method", "POST"}, {"path", "/api/config/reload"}, {"body", json::object()}});
  CHECK(action_object(request("POST", "/api/action", {{"linear", 1}})) ==
        json{{"type", "request"}, {"method", "POST"}, {"path", "/api/action"}, {"body", {{"linear", 1}}}});
}

TEST_CASE("no action, or something that is not a request, has no action object") {
  CHECK(action_object(nullptr).is_null());
  CHECK(action_object(json("drive")).is_null());
  CHECK(action_object(json{{"path", "/api/stop"}}).is_null());
  CHECK(action_object(json{{"method", 1}, {"path", "/api/stop"}}).is_null());
}
