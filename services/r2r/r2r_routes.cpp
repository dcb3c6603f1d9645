#include "services/r2r/r2r_routes.hpp"

#include <nlohmann/json.hpp>

#include "kernel/api/answers.hpp"
#include "libs/base/bounded_text.hpp"
#include "libs/base/json_body.hpp"
#include "services/r2r/r2r_service.hpp"

namespace rcand::services::r2r {

using namespace rcand::kernel;
namespace {

using nlohmann::json;

constexpr std::string_view kAuctionPrefix = "/api/r2r/auction/";
constexpr std::string_view kFleetPlugin = "org.rcand.fleet";  // runs the auctions (sdk::FleetAuctions)

http::Response answer(int status, const json& body) { return json_response(status, body); }

http::Response failure(int status, std::string code, std::string message, std::string field = {}) {
  return error_response(status, code, std::move(message), field.empty() ? json::object() : json{{"field", std::move(field)}});
}

// Auctions run in the fleet plugin; without it they are unavailable, not missing.
http::Response fleet_missing() {
  return error_response(503, "UNAVAILABLE",
                        "R2R auctions need the fleet plugin " + std::string(kFleetPlugin) +
                            ", which is not running on this robot (install rcand-plugins-core: it runs by itself "
                            "when runtime.r2r.enabled is true, or list it in rcan_protocol.capabilities)",
                        json{{"plugin", std::string(kFleetPlugin)}});
}

// POST /api/r2r/auction and GET /api/r2r/auction/<task_id>, answered by the fleet plugin; the audit entry of a POST
// is finished with its answer.
void handle_auction(R2rService& service, AuditLog& audit, Call& call, const Reply& respond, const json& body) {
  const sdk::FleetAuctions* fleet = service.fleet();
  if (fleet == nullptr) {
    if (call.audit_seq != 0) audit.finish(call.audit_seq, "failed", "no fleet plugin");
    return respond(fleet_missing());
  }
  if (call.request.method == "GET") {
    const sdk::Response result = fleet->result(call.request.path.substr(kAuctionPrefix.size()));
    return respond(answer(result.status, result.body));
  }
  service.request_auction(*fleet, body, [&audit, seq = call.audit_seq, respond](const sdk::Response& result) {
    const bool ok = result.status >= 200 && result.status < 300;
    auto text = [&result](const char* key) {
      const auto it = result.body.is_object() ? result.body.find(key) : result.body.end();
      return it != result.body.end() && it->is_string() ? it->get<std::string>() : std::string();
    };
    audit.finish(seq, ok ? "ok" : result.status < 500 ? "blocked" : "failed", ok ? "auction " + text("task_id") : text("error"));
    respond(answer(result.status, result.body));
  });
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
  if (request.method == "GET") return handle_auction(*service, audit, call, respond, json());

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
    const auto type = r2r_wire::parse_message_type(b["type"].get<std::string>());
    if (!type)
      return refuse(failure(400, "BAD_REQUEST",
                            "unknown R2R message type '" + bounded_text(b["type"].get<std::string>(), 64) + "'", "type"),
                    "unknown type");
    std::optional<std::string> target;
    if (b.contains("target") && !b["target"].is_null()) {
      if (!b["target"].is_string())
        return refuse(failure(400, "BAD_REQUEST", "target must be a robot name", "target"), "bad target");
      target = b["target"].get<std::string>();
    }
    const json payload = b.contains("payload") ? b["payload"] : json::object();
    auto sent = service->node().send_message(*type, payload, target);
    if (auto* error = std::get_if<r2r_wire::R2rError>(&sent)) {
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

  handle_auction(*service, audit, call, respond, body.value);  // POST /api/r2r/auction
}

}  // namespace

void add_r2r_routes(Router& router, R2rService* service, AuditLog& audit) {
  auto serve = [service, &audit](Call& call, Reply reply) { handle(service, audit, call, reply); };
  router.add({"GET", "/api/r2r/peers", sdk::Scope::Status}, serve);
  router.add({"POST", "/api/r2r/send", sdk::Scope::Control, true}, serve);
  router.add({"POST", "/api/r2r/auction", sdk::Scope::Control, true}, serve);
  router.add({"GET", std::string(kAuctionPrefix) + "*", sdk::Scope::Status}, serve);
}

}  // namespace rcand::services::r2r
