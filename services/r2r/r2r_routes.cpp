#include "services/r2r/r2r_routes.hpp"

#include <nlohmann/json.hpp>

#include <cmath>

#include "kernel/api/answers.hpp"
#include "libs/base/json_body.hpp"
#include "services/r2r/r2r_service.hpp"

namespace rcand::kernel {
namespace {

using nlohmann::json;

constexpr std::string_view kAuctionPrefix = "/api/r2r/auction/";
constexpr std::chrono::milliseconds kDefaultAuctionWait{30'000};
constexpr std::chrono::milliseconds kMaxAuctionWait{120'000};

http::Response answer(int status, const json& body) { return json_response(status, body); }

http::Response failure(int status, std::string code, std::string message, std::string field = {}) {
  return error_response(status, code, std::move(message), field.empty() ? json::object() : json{{"field", std::move(field)}});
}

// The task of POST /api/r2r/auction; an error names the field.
std::variant<r2r::TaskSpec, http::Response> read_task(const json& body) {
  r2r::TaskSpec task;
  auto bad = [](const std::string& field, const std::string& message) { return failure(400, "BAD_REQUEST", message, field); };
  if (!body.is_object()) return bad("body", "body must be a JSON object");
  if (body.contains("task_id")) {
    if (!body["task_id"].is_string()) return bad("task_id", "task_id must be a string");
    task.task_id = body["task_id"].get<std::string>();
  }
  if (body.contains("description")) {
    if (!body["description"].is_string()) return bad("description", "description must be a string");
    task.description = body["description"].get<std::string>();
  }
  if (body.contains("deadline") && !body["deadline"].is_null()) {
    if (!body["deadline"].is_number()) return bad("deadline", "deadline must be Unix seconds");
    task.deadline = body["deadline"].get<double>();
  }
  if (body.contains("required_capabilities")) {
    const auto& caps = body["required_capabilities"];
    if (!caps.is_array()) return bad("required_capabilities", "required_capabilities must be an array of strings");
    for (const auto& cap : caps) {
      if (!cap.is_string()) return bad("required_capabilities", "required_capabilities must be an array of strings");
      task.required_capabilities.push_back(cap.get<std::string>());
    }
  }
  if (body.contains("location") && !body["location"].is_null()) {
    const auto& location = body["location"];
    if (!location.is_object() || !location.contains("x") || !location.contains("y") || !location["x"].is_number() ||
        !location["y"].is_number() || !std::isfinite(location["x"].get<double>()) || !std::isfinite(location["y"].get<double>()))
      return bad("location", "location must be {\"x\": number, \"y\": number} in the fleet frame");
    task.location = r2r::FleetPoint{location["x"].get<double>(), location["y"].get<double>()};
  }
  return task;
}

void handle(R2rService* service, AuditLog& audit, Call& call, const Reply& respond) {
  const http::Request& request = call.request;
  if (service == nullptr) {
    if (call.audit_seq != 0) audit.finish(call.audit_seq, "blocked", "R2R disabled");
    respond(failure(404, "R2R_DISABLED", "R2R is not enabled on this robot (runtime.r2r.enabled)"));
    return;
  }
  if (request.path == "/api/r2r/peers") {
    respond(answer(200, service->peers()));
    return;
  }
  if (request.method == "GET") {
    const std::string task_id = request.path.substr(kAuctionPrefix.size());
    if (auto result = service->node().auction_result(task_id)) respond(answer(200, *result));
    else respond(failure(404, "NOT_FOUND", "this robot never opened an auction '" + task_id + "'"));
    return;
  }

  const std::uint64_t seq = call.audit_seq;  // POST rows are audited by the middleware
  auto refuse = [&](http::Response response, const std::string& why) {
    audit.finish(seq, "blocked", why);
    respond(std::move(response));
  };
  JsonBody body = parse_json_body(request.body);
  if (!body.error.empty()) return refuse(failure(400, "BAD_REQUEST", body.error, "body"), "bad body");

  if (request.path == "/api/r2r/send") {
    const json& b = body.value;
    if (!b.is_object() || !b.contains("type") || !b["type"].is_string())
      return refuse(failure(400, "BAD_REQUEST",
                            "body needs a string \"type\" (status, task_request, task_response, "
                            "command, negotiation, error)",
                            "type"),
                    "no type");
    const auto type = r2r::parse_message_type(b["type"].get<std::string>());
    if (!type)
      return refuse(failure(400, "BAD_REQUEST", "unknown R2R message type '" + b["type"].get<std::string>() + "'", "type"),
                    "unknown type");
    std::optional<std::string> target;
    if (b.contains("target") && !b["target"].is_null()) {
      if (!b["target"].is_string())
        return refuse(failure(400, "BAD_REQUEST", "target must be a robot name", "target"), "bad target");
      target = b["target"].get<std::string>();
    }
    const json payload = b.contains("payload") ? b["payload"] : json::object();
    auto sent = service->node().send_message(*type, payload, target);
    if (auto* error = std::get_if<r2r::R2rError>(&sent)) {
      return refuse(failure(400, "BAD_REQUEST", error->message, error->field.empty() ? "payload" : error->field),
                    "invalid message");
    }
    const r2r::SendOutcome& outcome = std::get<r2r::SendOutcome>(sent);
    // Queued, not sent: the transports take the message for delivery and nothing confirms it arrived (UDP, MQTT QoS 0,
    // a WebSocket write queue). No transport taking it (an unknown, unreachable target) is queued: false.
    const bool queued = !outcome.queued_on.empty();
    audit.finish(seq, queued ? "ok" : "failed",
                 std::string(target ? "to " + *target : "broadcast") + (queued ? "" : ": no transport could take it"));
    json message = json::parse(outcome.bytes, nullptr, false);
    if (message.is_object() && message.contains("header")) message["header"].erase("auth");  // never echo the token
    respond(answer(200, {{"queued", queued}, {"transports", outcome.queued_on}, {"message", message}}));
    return;
  }

  // POST /api/r2r/auction
  auto task = read_task(body.value);
  if (auto* bad = std::get_if<http::Response>(&task)) return refuse(std::move(*bad), "invalid task");
  bool wait = true;
  std::chrono::milliseconds timeout = kDefaultAuctionWait;
  if (body.value.contains("wait")) {
    if (!body.value["wait"].is_boolean())
      return refuse(failure(400, "BAD_REQUEST", "wait must be true or false", "wait"), "bad wait");
    wait = body.value["wait"].get<bool>();
  }
  if (body.value.contains("timeout_ms")) {
    const auto& value = body.value["timeout_ms"];
    if (!value.is_number_integer() || value.get<long long>() < 1 || value.get<long long>() > kMaxAuctionWait.count())
      return refuse(failure(400, "BAD_REQUEST", "timeout_ms must be an integer from 1 to 120000", "timeout_ms"), "bad timeout");
    timeout = std::chrono::milliseconds(value.get<long long>());
  }
  auto opened = service->node().open_auction(std::get<r2r::TaskSpec>(std::move(task)));
  if (auto* error = std::get_if<r2r::R2rError>(&opened))
    return refuse(failure(400, "BAD_REQUEST", error->message, error->field.empty() ? "body" : error->field), "invalid task");
  const std::string task_id = std::get<std::string>(opened);
  audit.finish(seq, "ok", "auction " + task_id);
  if (!wait) {
    respond(answer(202, {{"task_id", task_id}, {"state", "bidding"}}));
    return;
  }
  service->answer_when_decided(task_id, timeout, std::move(respond));
}

}  // namespace

void add_r2r_routes(Router& router, R2rService* service, AuditLog& audit) {
  auto serve = [service, &audit](Call& call, Reply reply) { handle(service, audit, call, reply); };
  router.add({"GET", "/api/r2r/peers", sdk::Scope::Status}, serve);
  router.add({"POST", "/api/r2r/send", sdk::Scope::Control, true}, serve);
  router.add({"POST", "/api/r2r/auction", sdk::Scope::Control, true}, serve);
  router.add({"GET", std::string(kAuctionPrefix) + "*", sdk::Scope::Status}, serve);
}

}  // namespace rcand::kernel
