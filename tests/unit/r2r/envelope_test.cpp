#include <doctest/doctest.h>

#include <string>

#include "libs/r2r_wire/envelope.hpp"

using namespace rcand::r2r_wire;
using nlohmann::json;

namespace {

json valid_status() {
  return {{"header", {{"version", "1.0"}, {"timestamp", 1718000000}, {"source_id", "robot_001"}}},
          {"type", "status"},
          {"payload", {{"battery", 85}, {"position", {{"x", 10.2}, {"y", 5.1}}}, {"task_progress", 0.75}}}};
}

R2rError refused(const std::string& bytes) {
  auto result = parse_envelope(bytes);
  REQUIRE_MESSAGE(std::holds_alternative<R2rError>(result), "accepted: ", bytes);
  return std::get<R2rError>(result);
}

R2rError refused(const json& message) { return refused(message.dump()); }

Envelope accepted(const json& message) {
  auto result = parse_envelope(message.dump());
  if (auto* error = std::get_if<R2rError>(&result)) FAIL("refused: ", error->message, " at ", error->field);
  return std::get<Envelope>(result);
}

}  // namespace

TEST_CASE("the seed's examples parse, and serialize round-trips them") {
  const Envelope status = accepted(valid_status());
  CHECK(status.type == MessageType::Status);
  CHECK(status.source_id == "robot_001");
  CHECK_FALSE(status.target_id);
  CHECK(status.timestamp == 1718000000.0);
  CHECK(status.payload["battery"] == 85);

  const json request{
      {"header", {{"version", "1.0"}, {"timestamp", 1718000001}, {"source_id", "bot_01"}, {"target_id", "bot_02"}}},
      {"type", "task_request"},
      {"payload", {{"task_id", "T001"}, {"description", "Pick up item at location (3.4, 6.7)"}, {"deadline", 1718000100}}}};
  const Envelope parsed = accepted(request);
  CHECK(parsed.target_id == "bot_02");
  const Envelope again = accepted(json::parse(serialize(parsed)));
  CHECK(again.payload == parsed.payload);
  CHECK(again.target_id == parsed.target_id);
  CHECK(again.type == MessageType::TaskRequest);

  const json response{
      {"header", {{"version", "1.0"}, {"timestamp", 1718000002}, {"source_id", "bot_02"}, {"target_id", "bot_01"}}},
      {"type", "task_response"},
      {"payload", {{"task_id", "T001"}, {"accepted", true}, {"estimated_time", 45}}}};
  CHECK(accepted(response).type == MessageType::TaskResponse);
  json negotiation = response;
  negotiation["type"] = "negotiation";
  negotiation["payload"] = {{"task_id", "T002"}, {"action", "bid"}, {"cost", 30}, {"capabilities", {"arm", "camera"}}};
  CHECK(accepted(negotiation).type == MessageType::Negotiation);
}

TEST_CASE("every required header field, missing or of the wrong type, is code 100 naming the field") {
  struct Case {
    const char* key;
    json wrong;
  };
  for (const Case& c : {Case{"version", 1.0}, Case{"timestamp", "1718000000"}, Case{"source_id", 7}}) {
    CAPTURE(c.key);
    json missing = valid_status();
    missing["header"].erase(c.key);
    const R2rError absent = refused(missing);
    CHECK(absent.code == ErrorCode::InvalidFormat);
    CHECK(absent.field == std::string("/header/") + c.key);

    json wrong = valid_status();
    wrong["header"][c.key] = c.wrong;
    const R2rError typed = refused(wrong);
    CHECK(typed.code == ErrorCode::InvalidFormat);
    CHECK(typed.field == std::string("/header/") + c.key);
    CHECK(typed.ref.has_value());  // the header is echoed for the error reply
  }
  json empty_source = valid_status();
  empty_source["header"]["source_id"] = "";
  CHECK(refused(empty_source).field == "/header/source_id");
  json bad_target = valid_status();
  bad_target["header"]["target_id"] = json::array();
  CHECK(refused(bad_target).field == "/header/target_id");
  json negative_time = valid_status();
  negative_time["header"]["timestamp"] = -5;
  CHECK(refused(negative_time).field == "/header/timestamp");

  for (const char* key : {"header", "type", "payload"}) {
    CAPTURE(key);
    json missing = valid_status();
    missing.erase(key);
    CHECK(refused(missing).field == std::string("/") + key);
    json wrong = valid_status();
    wrong[key] = 42;
    CHECK(refused(wrong).field == std::string("/") + key);
  }
}

TEST_CASE("unknown fields anywhere are ignored; an unknown type is code 100") {
  json extended = valid_status();
  extended["trace"] = {{"hops", 3}};
  extended["header"]["priority"] = "high";
  extended["payload"]["temperature_c"] = 41;
  const Envelope parsed = accepted(extended);
  CHECK(parsed.payload["temperature_c"] == 41);
  CHECK(parsed.received["trace"]["hops"] == 3);  // kept for signature checks

  json unknown = valid_status();
  unknown["type"] = "teleport";
  const R2rError error = refused(unknown);
  CHECK(error.code == ErrorCode::InvalidFormat);
  CHECK(error.field == "/type");
  CHECK(error.message.find("teleport") != std::string::npos);
  CHECK(error.source_id == "robot_001");
}

TEST_CASE("not JSON, not an object, oversized and deeply nested messages are code 100") {
  CHECK(refused(std::string("{\"header\":")).code == ErrorCode::InvalidFormat);
  CHECK(refused(std::string("[1,2,3]")).message.find("object") != std::string::npos);
  CHECK(refused(std::string("\xff\xfe")).code == ErrorCode::InvalidFormat);
  CHECK(refused(std::string()).code == ErrorCode::InvalidFormat);

  json big = valid_status();
  big["payload"]["padding"] = std::string(kMaxMessageBytes, 'x');
  const R2rError oversized = refused(big);
  CHECK(oversized.message.find("bytes") != std::string::npos);

  // Just under the limit passes: the limit is on size, not on content.
  json fits = valid_status();
  fits["payload"]["padding"] = std::string(kMaxMessageBytes - 400, 'x');
  accepted(fits);

  std::string deep(2000, '[');  // small in bytes, deep in nesting
  CHECK(refused(deep).message.find("nests deeper") != std::string::npos);
  json nested = valid_status();
  json inner = 1;
  for (int i = 0; i < kMaxMessageDepth + 2; ++i) inner = json::array({inner});
  nested["payload"]["x"] = inner;
  CHECK(refused(nested).message.find("nests deeper") != std::string::npos);
}

TEST_CASE("payloads are checked per type, naming the field") {
  auto with = [](const char* type, json payload) {
    json message = valid_status();
    message["type"] = type;
    message["payload"] = std::move(payload);
    return message;
  };
  struct Case {
    const char* type;
    json payload;
    const char* field;
  };
  const Case cases[] = {
      {"status", {{"battery", 150}}, "/payload/battery"},
      {"status", {{"battery", "full"}}, "/payload/battery"},
      {"status", {{"position", {{"x", 1}}}}, "/payload/position/y"},
      {"status", {{"task_progress", 1.5}}, "/payload/task_progress"},
      {"status", {{"estopped", "no"}}, "/payload/estopped"},
      {"status", {{"capabilities", {"nav", 3}}}, "/payload/capabilities/1"},
      {"task_request", json::object(), "/payload/task_id"},
      {"task_request", {{"task_id", ""}}, "/payload/task_id"},
      {"task_request", {{"task_id", "T"}, {"required_capabilities", "nav"}}, "/payload/required_capabilities"},
      {"task_request", {{"task_id", "T"}, {"location", {{"x", "1"}, {"y", 2}}}}, "/payload/location/x"},
      {"task_request", {{"task_id", "T"}, {"bid_deadline", "soon"}}, "/payload/bid_deadline"},
      {"task_response", {{"task_id", "T"}}, "/payload/accepted"},
      {"task_response", {{"task_id", "T"}, {"accepted", "yes"}}, "/payload/accepted"},
      {"task_response", {{"task_id", "T"}, {"accepted", true}, {"estimated_time", -1}}, "/payload/estimated_time"},
      {"negotiation", {{"task_id", "T"}}, "/payload/action"},
      {"negotiation", {{"task_id", "T"}, {"action", "haggle"}}, "/payload/action"},
      {"negotiation", {{"task_id", "T"}, {"action", "bid"}}, "/payload/cost"},
      {"negotiation", {{"task_id", "T"}, {"action", "bid"}, {"cost", 3}, {"capabilities", {1}}}, "/payload/capabilities/0"},
      {"command", json::object(), "/payload/type"},
      {"command", {{"type", 5}}, "/payload/type"},
      {"error", {{"message", "x"}}, "/payload/code"},
      {"error", {{"code", 100.5}, {"message", "x"}}, "/payload/code"},
      {"error", {{"code", 100}}, "/payload/message"},
      {"error", {{"code", 100}, {"message", "x"}, {"ref", "h"}}, "/payload/ref"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.type);
    CAPTURE(c.payload.dump());
    const R2rError error = refused(with(c.type, c.payload));
    CHECK(error.code == ErrorCode::InvalidFormat);
    CHECK(error.field == c.field);
  }
  accepted(with("status", {{"battery", nullptr},
                           {"position", nullptr},
                           {"task_progress", nullptr},
                           {"state", "idle"},
                           {"estopped", false},
                           {"capabilities", {"nav"}}}));
  accepted(with("task_request", {{"task_id", "T"},
                                 {"required_capabilities", {"nav"}},
                                 {"location", {{"x", 1}, {"y", 2}}},
                                 {"bid_deadline", 1718000003.5}}));
  accepted(with("negotiation", {{"task_id", "T"}, {"action", "award"}}));
  accepted(with("negotiation", {{"task_id", "T"}, {"action", "withdraw"}}));
  accepted(with("command", {{"type", "move"}, {"linear", 0.3}, {"duration_ms", 200}}));
  accepted(with("error", {{"code", 104}, {"message", "late"}, {"ref", {{"source_id", "a"}}}}));
}

TEST_CASE("error payloads carry code, message and ref") {
  const json ref{{"version", "1.0"}, {"timestamp", 1}, {"source_id", "a"}};
  const json payload = make_error_payload(ErrorCode::TaskAssigned, "taken", ref);
  CHECK(payload["code"] == 102);
  CHECK(payload["message"] == "taken");
  CHECK(payload["ref"] == ref);
  CHECK_FALSE(make_error_payload(ErrorCode::InvalidFormat, "bad", std::nullopt).contains("ref"));
  CHECK(error_code_name(105) == "estop_active");
  CHECK(error_code_name(104) == "network_timeout");
}

TEST_CASE("the received header is echoed without credentials") {
  json message = valid_status();
  message["header"]["auth"] = {{"token", "secret-token"}};
  message["header"]["signature"] = {{"key_id", "k"}, {"sig", "AAAA"}};
  message["payload"]["battery"] = "bad";
  const R2rError error = refused(message);
  REQUIRE(error.ref);
  CHECK_FALSE(error.ref->contains("auth"));
  CHECK_FALSE(error.ref->contains("signature"));
  CHECK((*error.ref)["source_id"] == "robot_001");
}

TEST_CASE("the echoed header is the seed's fields only, bounded, whatever the sender packed into it") {
  json message = valid_status();
  message["header"]["padding"] = std::string(40'000, 'x');  // an extension field: not echoed (64 KiB in all)
  message["header"]["version"] = std::string(10'000, 'v');  // a wrong-but-string field: cut
  message["payload"]["battery"] = "bad";
  const R2rError error = refused(message);
  REQUIRE(error.ref);
  CHECK_FALSE(error.ref->contains("padding"));
  CHECK((*error.ref)["source_id"] == "robot_001");
  CHECK(error.ref->dump().size() < 600);  // was the whole 50 KB header, echoed to every bad message
}
