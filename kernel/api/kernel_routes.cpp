#include "kernel/api/kernel_routes.hpp"

#include <charconv>

#include "kernel/api/answers.hpp"
#include "kernel/safety/stop_summary.hpp"
#include "libs/base/bounded_text.hpp"
#include "libs/base/json_body.hpp"
#include "libs/base/plugin_health.hpp"

namespace rcand::kernel {
namespace {

using nlohmann::json;
using sdk::Scope;

constexpr std::size_t kMaxAuditLimit = 10000;

// POST /api/stop: latch first (every actuator halted in parallel), report after. The stop never fails on its body:
// a malformed body still stops the robot.
void stop(const KernelRouteDeps& d, Call& call, const Reply& reply) {
  // On the kernel's steady clock (the sim drive's timeline clock), so a test can compare it with the halt events.
  const std::int64_t received_us = d.clock.now_us();
  // Who and from where, for GET /api/estop's summary (docs/protocol.md §6.7): the body's optional "reason" and "from".
  Estop::Origin origin{call.principal, "request", {}, {}};
  if (auto body = parse_json_body(call.request.body); body.error.empty() && body.value.is_object()) {
    const auto text = [&body](const char* key, std::size_t limit) {
      const auto it = body.value.find(key);  // never cut inside a UTF-8 character
      return it != body.value.end() && it->is_string() ? bounded_text(it->get<std::string>(), limit) : std::string();
    };
    origin.note = text("reason", 200);
    origin.from = text("from", 80);
  }
  if (const auto peer = call.request.header("x-swarm-forwarded")) {  // a peer's broadcast (docs/protocol.md §9.2)
    origin.kind = "swarm";
    origin.from = bounded_text(std::string(*peer), 200);
  }
  // The on-latch listeners and the log line run after the answer was sent (when `latched` goes out of scope).
  const Estop::Announcement latched{
      d.estop, d.estop.latch_unannounced(origin.note.empty() ? "POST /api/stop" : origin.note, call.principal, origin)};
  json drivers = json::array();
  bool all_halted = true;
  for (const auto& halt : latched.report.drivers) {
    json entry{{"id", halt.id}, {"halted", halt.halted}, {"latency_us", halt.latency_us}, {"state", halt.state}};
    if (!halt.error.empty()) entry["error"] = halt.error;  // the slow or failing driver, named
    drivers.push_back(std::move(entry));
    all_halted = all_halted && halt.halted;
  }
  d.audit.finish(call.audit_seq, "ok");
  reply(json_response(200, {{"status", "stopped"},
                            {"estopped", true},
                            {"motors_stopped", all_halted},
                            {"drivers", drivers},
                            {"latency_us", latched.report.latency_us},
                            {"received_us", received_us}}));
}

void estop_state(const KernelRouteDeps& d, const Reply& reply) { reply(json_response(200, estop_document(d.estop.snapshot()))); }

void estop_clear(const KernelRouteDeps& d, Call& call, const Reply& reply) {
  const bool was = d.estop.clear();
  d.audit.finish(call.audit_seq, "ok", was ? "" : "was not latched");
  reply(json_response(200, {{"status", "cleared"}, {"was_latched", was}}));
}

void health(const KernelRouteDeps& d, const Reply& reply) {
  reply(json_response(200,
                      {{"status", "ok"}, {"uptime_s", (d.clock.now_us() - d.started_us) / 1'000'000}, {"version", d.version}}));
}

// The snapshot as published, serialized once per change: no plugin code, no thread hop. when_current() answers at
// once unless a publish or a failure is not in the snapshot yet (then at the next rebuild, within 20 ms).
void status(const KernelRouteDeps& d, const Reply& reply) {
  d.status.when_current([reply](std::shared_ptr<const std::string> body) {
    http::Response response;
    response.body = *body;
    reply(std::move(response));
  });
}

void audit_entries(const KernelRouteDeps& d, Call& call, const Reply& reply) {
  std::size_t limit = 100;
  if (auto it = call.request.query.find("limit"); it != call.request.query.end()) {
    // The whole value, digits only: "-5" (which stoul would wrap around) and "5abc" are refused, not guessed at.
    const std::string& text = it->second;
    std::size_t parsed = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), parsed);
    if (ec != std::errc{} || end != text.data() + text.size() || parsed == 0 || parsed > kMaxAuditLimit) {
      reply(error_response(400, "BAD_REQUEST", "limit must be an integer in [1, " + std::to_string(kMaxAuditLimit) + "]",
                           {{"field", "limit"}}));
      return;
    }
    limit = parsed;
  }
  reply(json_response(200, d.audit.to_json(limit)));
}

// Each plugin's library record, with its driver and capability instances as the status snapshot shows them and the
// health they add up to: a loaded library whose driver failed is not "ok".
void plugins(const KernelRouteDeps& d, Call& call, const Reply& reply) {
  // File paths only for a credential granting config (its scopes: an OWNER JWT narrowed to status does not).
  json plugins = d.host.to_json(call.has_scope(Scope::Config));
  add_plugin_health(plugins, d.status.document(), true);
  reply(json_response(200, {{"plugins", std::move(plugins)}}));
}

// POST /api/plugins/<id>/reload (docs/protocol.md §7.15): answered when the reload is over; audited either way.
void plugin_reload(const KernelRouteDeps& d, Call& call, const Reply& reply) {
  constexpr std::string_view kPrefix = "/api/plugins/", kSuffix = "/reload";
  const std::string& path = call.request.path;
  if (!path.ends_with(kSuffix) || path.size() <= kPrefix.size() + kSuffix.size()) {
    d.audit.finish(call.audit_seq, "blocked", "no such route");
    return reply(error_response(404, "NOT_FOUND", "the plugin action is POST /api/plugins/<id>/reload"));
  }
  const std::string id = path.substr(kPrefix.size(), path.size() - kPrefix.size() - kSuffix.size());
  d.reload_plugin(id, call.principal, [audit = &d.audit, seq = call.audit_seq, reply](int status, json body) {
    const std::string code = body.value("code", "");
    audit->finish(seq, status == 200 ? "ok" : "error", code);
    if (status == 200) return reply(json_response(200, body));
    const std::string why = body.value("error", "plugin reload failed");
    body.erase("error");
    body.erase("code");
    reply(error_response(status, code, why, body));
  });
}

void driver(const KernelRouteDeps& d, Call& call, const Reply& reply) {
  const std::string id = call.request.path.substr(std::string_view("/api/drivers/").size());
  for (const auto& instance : d.runtime.drivers()) {
    if (instance.id != id) continue;
    auto status = d.runtime.status_of(instance);  // first: a status() that hangs fails the driver
    json doc{{"id", instance.id},
             {"protocol", instance.protocol},
             {"plugin", instance.plugin_id},
             {"state", instance.health.failed() ? "failed" : "ok"}};
    if (instance.health.failed()) StatusBoard::add_fault(doc, instance.health.fault());
    else if (auto fault = status ? StatusBoard::reported_fault(*status) : std::nullopt)
      doc.update({{"state", "error"}, {"reason", *fault}});
    if (status) doc["status"] = std::move(*status);
    reply(json_response(200, doc));
    return;
  }
  reply(error_response(404, "NOT_FOUND", "no driver '" + bounded_text(id) + "'"));
}

}  // namespace

void add_kernel_routes(Router& router, const KernelRouteDeps& deps) {
  const KernelRouteDeps* d = &deps;
  // method, path, scope, audited, motion, rate-limited
  router.add({"GET", "/health", Scope::None}, [d](Call&, Reply reply) { health(*d, reply); });
  router.add({"GET", "/api/status", Scope::Status}, [d](Call&, Reply reply) { status(*d, reply); });
  router.add({"GET", "/api/discovery", Scope::None}, [d](Call&, Reply reply) { reply(json_response(200, d->discovery())); });
  router.add(
      {.method = "POST", .path = "/api/stop", .scope = Scope::Status, .audited = true, .rate_limited = false, .stop = true},
      [d](Call& call, Reply reply) { stop(*d, call, reply); });
  router.add({"GET", "/api/estop", Scope::Status, false, false, false}, [d](Call&, Reply reply) { estop_state(*d, reply); });
  router.add({"POST", "/api/estop/clear", Scope::Config, true, false, false},
             [d](Call& call, Reply reply) { estop_clear(*d, call, reply); });
  router.add({"GET", "/api/audit", Scope::Config}, [d](Call& call, Reply reply) { audit_entries(*d, call, reply); });
  router.add({"GET", "/api/plugins", Scope::Status}, [d](Call& call, Reply reply) { plugins(*d, call, reply); });
  router.add({"GET", "/api/drivers/*", Scope::Status}, [d](Call& call, Reply reply) { driver(*d, call, reply); });
  router.add({"POST", "/api/plugins/*", Scope::Config, true}, [d](Call& call, Reply reply) { plugin_reload(*d, call, reply); });
}

}  // namespace rcand::kernel
