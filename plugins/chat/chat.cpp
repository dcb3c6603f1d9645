#include "chat.hpp"

#include <rcand/sdk/bounded_text.hpp>
#include <rcand/sdk/interfaces/pose_source.hpp>
#include <rcand/sdk/interfaces/request_dispatcher.hpp>
#include <rcand/sdk/request_body.hpp>

#include <random>
#include <stdexcept>
#include <variant>

#include "action_check.hpp"
#include "action_object.hpp"
#include "brain_metrics.hpp"
#include "injection_scan.hpp"
#include "proposal_guard.hpp"

namespace rcand::plugins::chat {
namespace {

using sdk::Json;
using sdk::Response;
using Clock = std::chrono::steady_clock;

// "th-" and 16 hex digits: also the dispatched request's message id (the kernel accepts [A-Za-z0-9._-]{1,64}),
// so the audit entry of what a thought did carries the thought's id.
std::string new_thought_id() {
  thread_local std::mt19937_64 random{std::random_device{}()};
  char text[24];
  std::snprintf(text, sizeof text, "th-%016llx", static_cast<unsigned long long>(random()));
  return text;
}

const std::string kThoughtsPrefix = "/api/thoughts/";
constexpr std::chrono::microseconds kCleanupDelay{1000};

bool is_thought_id(const std::string& id) {
  if (id.size() != 19 || id.rfind("th-", 0) != 0) return false;
  return id.find_first_not_of("0123456789abcdef", 3) == std::string::npos;
}

// An error answer that still says what the brain thought.
Response refusal(int status, std::string code, std::string message, const Json& answer, Json extra = Json::object()) {
  Json body = answer;
  body.update(extra);
  return Response::error(status, std::move(code), std::move(message), std::move(body));
}

// rcand's answer when it did not run a dispatched request because the caller's credential no longer allows it.
bool caller_unauthorized(const Json& body) {
  const auto code = body.is_object() ? body.find("code") : body.end();
  return code != body.end() && (*code == "UNAUTHORIZED" || *code == "INSUFFICIENT_PRIVILEGES");
}

// What the approver is answered when rcand refused the instruction's caller at dispatch: not the 401/403 itself (the
// approver's own credential is fine, and a client that sees 401 drops its token), but 409 naming the caller.
Response caller_refused(Response r, const std::string& caller) {
  Json body = std::move(r.body);
  body["caller_status"] = r.status;
  body["caller_code"] = body.value("code", "");
  return Response::error(409, "CALLER_UNAUTHORIZED",
                         "the instruction's caller '" + caller + "' is no longer authorized for this action (" +
                             std::to_string(r.status) + "); nothing was dispatched",
                         std::move(body));
}

// A dispatch's outcome for the thought log.
std::string dispatched_state(const Response& r) { return caller_unauthorized(r.body) ? "refused" : "dispatched"; }

// Why an action was not put in the HiTL queue (docs/protocol.md §7.5: a share per principal).
Response hitl_refusal(HitlQueue::Admission why, const HitlQueue::Limits& limits, const Json& answer, const std::string& reason) {
  const Json hitl{{"state", "refused"}, {"reason", reason}};
  switch (why) {
    case HitlQueue::Admission::OverShare:
      return refusal(429, "TOO_MANY_PENDING",
                     "you already have " + std::to_string(limits.per_principal) +
                         " actions waiting for approval (runtime.capabilities.chat.hitl_per_principal)",
                     answer, Json{{"hitl", hitl}, {"limit", limits.per_principal}});
    case HitlQueue::Admission::Reserved:
      return refusal(503, "HITL_SLOTS_RESERVED",
                     "the human-in-the-loop queue's last " + std::to_string(limits.reserved) +
                         " slots are kept for OWNER and CREATOR (runtime.capabilities.chat.hitl_reserved)",
                     answer, Json{{"hitl", hitl}, {"limit", limits.limit}});
    default:
      return refusal(503, "UNAVAILABLE", "the human-in-the-loop queue is full (runtime.capabilities.chat.hitl_limit)", answer,
                     Json{{"hitl", hitl}, {"limit", limits.limit}});
  }
}

}  // namespace

struct Chat::Thought {
  std::string id;
  sdk::Request request;  // the caller: principal, role, message_id
  CommandInput input;
  std::shared_ptr<sdk::StreamWriter> writer;
  std::uint64_t epoch = 0;  // chat's e-stop epoch when the instruction came in
  Clock::time_point deadline;
  Json ai;  // who decided: the audit note of the dispatched request ({"ai": ...}), set once a brain answered
};

Chat::Chat(sdk::PluginContext& ctx)
    : ctx_(ctx),
      settings_(read_chat_settings(ctx.config(), ctx.robot_config())),
      pool_(ctx, settings_.workers, settings_.queue_limit),
      thoughts_(settings_.thought_log_size),
      hitl_({settings_.hitl_limit, settings_.hitl_per_principal, settings_.hitl_reserved}),
      timer_(ctx.worker("deadline")),
      canceller_(ctx.worker("estop")) {
  for (const auto& brain : settings_.model_brains) {
    model_brains_.push_back(std::make_unique<ModelBrain>(brain));
    if (!brain.api_key.empty()) secrets_.push_back(brain.api_key);
    // Never the key: where it comes from is enough to debug with.
    ctx_.log().info("brain '", brain.provider, "': ", brain.format == WireFormat::OpenAI ? "OpenAI-compatible" : "Ollama", " at ",
                    brain.url, ", model ", brain.model, ", timeout ", brain.timeout.count(), " ms",
                    brain.key_source.empty() ? std::string() : ", API key from " + brain.key_source);
    if (!brain.setup_error.empty()) ctx_.log().warn("brain '", brain.provider, "' cannot work: ", brain.setup_error);
    if (brain.timeout > settings_.timeout || brain.first_byte_timeout > settings_.timeout)
      ctx_.log().warn("brain '", brain.provider, "': its timeouts exceed chat's deadline of ", settings_.timeout.count(),
                      " ms; a slow (cold) model load is cut off there - raise runtime.capabilities.chat.timeout_ms and "
                      "runtime.handler_timeout_ms (chat keeps ",
                      kHandlerMargin.count(), " ms of it)");
  }
  for (const auto& line : settings_.ignored) ctx_.log().warn(line);
  if (settings_.timeout_capped)
    ctx_.log().warn("runtime.capabilities.chat.timeout_ms is cut to ", settings_.timeout.count(),
                    " ms: the kernel answers 503 after runtime.handler_timeout_ms; raise that for slow models");
  std::string chain;
  for (const auto& p : settings_.providers) chain += (chain.empty() ? "" : " -> ") + p;
  ctx_.log().info("brains: ", chain, " within ", settings_.timeout.count(), " ms; ", settings_.workers, " at once, ",
                  settings_.queue_limit, " waiting; ", settings_.phrases.size(), " configured phrases, ", settings_.gates.size(),
                  " confidence gates, ", settings_.hitl_gates.size(), " HiTL gates");
}

Chat::~Chat() { shutdown(); }

void Chat::start() {
  declare_brain_metrics(ctx_);
  // chat's HTTP brains are Brain services like any plugin's: the chain finds every brain one way, and another
  // plugin can ask the robot's configured model too. One provider per name: a clash is a named fault, never a
  // silent choice between two brains.
  for (const auto& b : model_brains_)
    if (!ctx_.offer_service(sdk::brain_service_id(b->provider()), static_cast<const sdk::Brain*>(b.get())))
      throw std::runtime_error("brain '" + std::string(b->provider()) +
                               "' is configured in runtime.capabilities.chat.brains and offered by another plugin too: "
                               "give one of them another provider name");
  if (model_brains_.empty()) return;
  health_ = &ctx_.worker("health");
  for (std::size_t i = 0; i < model_brains_.size(); ++i) health_->post([this, i] { probe(i); });
}

// One brain's probe, then the next one scheduled; a probe blocks only the health worker.
void Chat::probe(std::size_t brain) noexcept {
  sdk::CancelToken token;
  {
    std::lock_guard lock(probes_.mutex);
    if (probes_.stopped) return;
    probes_.running = token;
  }
  const auto& b = *model_brains_[brain];
  const Json health =
      b.probe(std::min(b.settings().connect_timeout + std::chrono::milliseconds(1000), std::chrono::milliseconds(5000)), token);
  if (!health.value("ok", false)) ctx_.log().warn("brain '", b.provider(), "' health probe: ", health.value("error", "failed"));
  ctx_.publish_status(status());
  std::lock_guard lock(probes_.mutex);
  if (probes_.stopped) return;
  probes_.timers.push_back(health_->schedule(b.settings().health_interval, [this, brain] { probe(brain); }));
  if (probes_.timers.size() > 4 * model_brains_.size())  // fired timers need no cancelling
    probes_.timers.erase(probes_.timers.begin(), probes_.timers.end() - static_cast<long>(model_brains_.size()));
}

std::vector<sdk::Route> Chat::routes() {
  return {{"GET", kThoughtsPrefix + "*", sdk::Scope::Control, false, "", [this](const sdk::Request& r) { return thought(r); }},
          {"GET", "/api/hitl/pending", sdk::Scope::Control, false, "", [this](const sdk::Request& r) { return pending(r); }}};
}

std::vector<sdk::StreamRoute> Chat::stream_routes() {
  return {{"POST", "/api/command", sdk::Scope::Control,
           [this](const sdk::Request& request, std::shared_ptr<sdk::StreamWriter> writer) { command(request, writer); }},
          {"POST", "/api/hitl/authorize", sdk::Scope::Config,
           [this](const sdk::Request& request, std::shared_ptr<sdk::StreamWriter> writer) { authorize(request, writer); }}};
}

void Chat::answer(const Thought& thought, const std::string& state, Response response,
                  std::vector<std::pair<std::string, std::string>> headers) {
  Json fields{{"state", state}, {"status", response.status}};
  if (response.status >= 300 && response.body.contains("code")) fields["code"] = response.body["code"];
  thoughts_.update(thought.id, fields);
  thought.writer->respond(response, std::move(headers));
  ctx_.publish_status(status());  // GET /api/status serves the snapshot; counters changed
}

void Chat::command(const sdk::Request& request, const std::shared_ptr<sdk::StreamWriter>& writer) {
  ++counters_.received;
  auto input = read_command(request.body, settings_.max_instruction_chars, settings_.max_image_bytes);
  if (auto* bad = std::get_if<Response>(&input)) {
    ++counters_.refused;
    writer->respond(*bad);
    return;
  }
  auto thought = std::make_shared<Thought>();
  thought->id = new_thought_id();
  thought->request = request;
  thought->request.body = nullptr;  // the input is kept parsed; the body may hold a large image
  thought->input = std::move(std::get<CommandInput>(input));
  thought->writer = writer;
  thought->epoch = epoch_.load();
  thought->deadline = Clock::now() + settings_.timeout;
  thoughts_.add(thought->id, {{"thought_id", thought->id},
                              {"created_at_ms", ctx_.clock().wall_ms()},
                              {"principal", request.principal},
                              {"role", sdk::role_name(request.role)},
                              {"message_id", request.message_id},
                              {"instruction", thought->input.instruction},
                              {"image", !thought->input.image_b64.empty()},
                              {"state", "queued"}});

  auto job = std::make_shared<BrainPool::Job>();
  job->run = [this, thought](const sdk::CancelToken& cancel) { think(thought, cancel); };
  job->epoch = thought->epoch;
  job->drop = [this, thought](bool stopping) {
    ++counters_.cancelled;
    const Json extra{{"thought_id", thought->id}, {"dispatched", false}};
    if (stopping) answer(*thought, "cancelled", Response::error(503, "UNAVAILABLE", "chat is shutting down; not read", extra));
    else
      answer(*thought, "cancelled",
             Response::error(423, "ESTOP_ACTIVE", "the e-stop latched before this instruction was read; dropped", extra));
  };
  switch (pool_.submit(job)) {
    case BrainPool::Admission::Queued: return;
    case BrainPool::Admission::Stopped:
      answer(*thought, "cancelled", Response::error(503, "UNAVAILABLE", "chat is shutting down"));
      return;
    case BrainPool::Admission::Full: break;
  }
  ++counters_.busy;
  answer(*thought, "refused",
         Response::error(429, "BUSY",
                         "chat is busy: " + std::to_string(pool_.capacity()) +
                             " instructions are being read or wait (runtime.capabilities.chat.workers + queue_limit)",
                         Json{{"limit", pool_.capacity()}, {"thought_id", thought->id}}),
         {{"Retry-After", "1"}});
}

sdk::BrainContext Chat::context() const {
  sdk::BrainContext c;
  c.capabilities = settings_.limits.declared;
  c.phrases = settings_.phrases;
  c.limits = limits_json(settings_.limits);
  if (const auto* pose = sdk::find<sdk::PoseSource>(ctx_))
    if (const auto reading = pose->read(); reading.available) c.pose = reading.pose;
  return c;
}

// The chain: each provider in turn until one answers without an error; the grammar brain is always last and keeps
// kGrammarReserve of the deadline. A provider nothing offers counts as an error, so the chain moves on.
sdk::Proposal Chat::ask_brains(const Thought& thought, const sdk::BrainContext& context, const sdk::CancelToken& cancel,
                               Json& attempts) {
  sdk::Proposal last;
  for (const auto& provider : settings_.providers) {
    if (cancel.cancelled()) break;
    const auto started = Clock::now();
    sdk::BrainRequest request{thought.input.instruction, thought.input.image_b64, thought.deadline - kGrammarReserve};
    sdk::Proposal p;
    const sdk::Brain* brain = provider == GrammarBrain::kProvider
                                  ? nullptr
                                  : static_cast<const sdk::Brain*>(ctx_.service(sdk::brain_service_id(provider)));
    if (provider == GrammarBrain::kProvider) {
      request.deadline = thought.deadline;
      p = grammar_.propose(request, context, cancel);
    } else if (brain == nullptr) {
      p.error = "no plugin offers the brain '" + provider + "'";
    } else if (request.deadline <= started) {
      p.error = "no time left before chat's deadline";
    } else {
      // Its own token, cancelled by the thought's (an e-stop) or by the deadline, so a timeout moves the chain on.
      sdk::CancelToken attempt;
      cancel.on_cancel([attempt] { attempt.cancel(); });
      const auto remaining = std::chrono::duration_cast<std::chrono::microseconds>(request.deadline - started);
      const auto timer = timer_.schedule(remaining, [attempt] { attempt.cancel(); });
      p = brain->propose(request, context, attempt);
      timer_.cancel(timer);
      if (attempt.cancelled() && !cancel.cancelled()) {
        p.error = "no answer before chat's deadline (" + std::to_string(settings_.timeout.count()) + " ms)";
        p.action = nullptr;
      }
    }
    if (p.brain.empty()) p.brain = provider;
    // The one place every brain's answer passes before anything stores, logs, answers or dispatches it: every API key
    // chat knows redacted from every text and the action, every text bounded (proposal_guard.hpp).
    p = guard_proposal(std::move(p), secrets_);
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - started).count();
    attempts.push_back({{"brain", provider}, {"latency_ms", ms}, {"error", p.error.empty() ? Json(nullptr) : Json(p.error)}});
    record_brain_call(ctx_, provider, p, Clock::now() >= request.deadline, attempts.size() > 1, Clock::now() - started);
    if (p.error.empty()) return p;
    ++counters_.brain_failures;
    ctx_.log().warn("thought ", thought.id, ": brain '", provider, "' failed (", p.error, "); next in the chain");
    last = std::move(p);
  }
  if (last.error.empty()) last.error = "cancelled";
  return last;
}

void Chat::think(const std::shared_ptr<Thought>& thought, const sdk::CancelToken& cancel) noexcept {
  const auto cancelled = [&] {
    ++counters_.cancelled;
    answer(
        *thought, "cancelled",
        Response::error(423, "ESTOP_ACTIVE", "the e-stop latched while this instruction was being read; nothing was dispatched",
                        Json{{"thought_id", thought->id}, {"dispatched", false}}));
  };
  try {
    if (cancel.cancelled() || epoch_.load() != thought->epoch) return cancelled();
    thoughts_.update(thought->id, {{"state", "thinking"}});

    // Gate: the injection scan, before any brain sees the text.
    if (const auto verdict = scan_for_injection(thought->input.instruction); verdict.blocked) {
      ++counters_.injection_blocked;
      ctx_.log().warn("INJECTION_BLOCKED thought ", thought->id, " message ", thought->request.message_id, " from '",
                      thought->request.principal, "': rule ", verdict.rule, "; no brain was asked");
      thoughts_.update(thought->id, {{"injection_rule", verdict.rule}});
      answer(*thought, "blocked",
             Response::error(403, "INJECTION_BLOCKED", "the instruction looks like a prompt injection; it was not read",
                             Json{{"field", "instruction"},
                                  {"reason", "prompt_injection"},
                                  {"rule", verdict.rule},
                                  {"thought_id", thought->id}}));
      return;
    }

    Json attempts = Json::array();
    const sdk::Proposal p = ask_brains(*thought, context(), cancel, attempts);
    if (cancel.cancelled() || epoch_.load() != thought->epoch) return cancelled();
    // `action` in the ecosystem's shape ({"type": ...}), `request` the request it dispatches (docs/protocol.md §7.5).
    Json answer_body{{"raw_text", p.raw_text}, {"action", action_object(p.action)}, {"request", p.action}, {"brain", p.brain},
                     {"model", p.model},       {"thought_id", thought->id},         {"dispatched", false}};
    if (p.confidence) answer_body["confidence"] = *p.confidence;  // absent stays absent: never a made-up 1.0
    if (attempts.size() > 1) answer_body["attempts"] = attempts;
    Json record{{"brain", p.brain},
                {"model", p.model},
                {"raw_text", p.raw_text},
                {"action", bounded_json(answer_body["action"])},
                {"request", bounded_json(p.action)},
                {"attempts", attempts},
                {"inference_latency_ms", attempts.back()["latency_ms"]}};
    if (p.confidence) record["confidence"] = *p.confidence;
    thoughts_.update(thought->id, record, p.reasoning);
    thought->ai = {{"provider", p.brain},
                   {"model", p.model},
                   {"confidence", p.confidence ? Json(*p.confidence) : Json(nullptr)},
                   {"inference_latency_ms", attempts.back()["latency_ms"]},
                   {"thought_id", thought->id}};
    if (!p.error.empty()) {
      answer(*thought, "failed", refusal(503, "UNAVAILABLE", "no brain answered: " + p.error, answer_body),
             {{"Retry-After", "1"}});
      return;
    }
    if (p.action.is_null()) {
      ++counters_.not_understood;
      answer(*thought, "not_understood",
             refusal(422, "NOT_UNDERSTOOD", p.raw_text.empty() ? "not understood" : p.raw_text, answer_body,
                     Json{{"field", "instruction"}, {"suggestions", p.suggestions}}));
      return;
    }
    auto checked = check_action(p.action, settings_.limits);
    if (auto* bad = std::get_if<Response>(&checked)) {
      ++counters_.refused;
      ctx_.log().warn("thought ", thought->id, ": brain '", p.brain, "' proposed a refused action (",
                      bad->body.value("error", ""), "); nothing was dispatched");
      Json body = answer_body;
      body.update(bad->body);
      answer(*thought, "refused", Response{bad->status, std::move(body)});
      return;
    }
    const auto& action = std::get<CheckedAction>(checked);
    // Gate: confidence. A stop is never held back: neither blocked by a low confidence nor kept waiting for a human.
    const auto gate = apply_confidence_gates(settings_.gates, p.confidence, action.scope, action.capability);
    if (!gate.passed && gate.outcome == ConfidenceGate::OnFail::Block && !action.stop) {
      ++counters_.gate_blocked;
      answer(*thought, "refused",
             refusal(422, "CONFIDENCE_TOO_LOW",
                     p.confidence ? "the brain's confidence is below agent.confidence_gates"
                                  : "the brain gave no confidence, which no gate accepts",
                     answer_body, Json{{"on_fail", "block"}, {"min_confidence", gate.threshold}}));
      return;
    }
    if (!gate.passed && gate.outcome == ConfidenceGate::OnFail::Allow)
      answer_body["confidence_gate"] = "allowed below min_confidence " + Json(gate.threshold).dump();
    // Gate: human in the loop - a HiTL gate naming the action, or a confidence gate escalating it.
    const HitlGate* hitl = action.stop ? nullptr : matching_hitl_gate(settings_.hitl_gates, action.scope, action.capability);
    const bool escalated = !gate.passed && gate.outcome == ConfidenceGate::OnFail::Escalate && !action.stop;
    if (hitl != nullptr || escalated) {
      if (escalated) answer_body["min_confidence"] = gate.threshold;
      hold(thought, answer_body, action, escalated ? "confidence_escalation" : "hitl_gate",
           hitl ? hitl->timeout : settings_.escalation_timeout, hitl ? hitl->approve_on_timeout : false);
      return;
    }
    dispatch(thought, answer_body, action, [this, thought](Response r) {
      const std::string state = dispatched_state(r);
      answer(*thought, state, std::move(r));
    });
  } catch (const std::exception& e) {
    ctx_.log().error("thought ", thought->id, ": ", e.what());
    answer(*thought, "failed",
           Response::error(500, "INTERNAL", "chat failed reading this instruction", Json{{"thought_id", thought->id}}));
  }
}

// Parks the action for a human: the caller gets 202 now; the decision (or the timeout, or an e-stop) runs it or not.
void Chat::hold(const std::shared_ptr<Thought>& thought, const Json& answer_body, const CheckedAction& action,
                const std::string& reason, std::chrono::milliseconds timeout, bool approve_on_timeout) {
  const std::int64_t expires = ctx_.clock().wall_ms() + timeout.count();
  Json summary{{"thought_id", thought->id},
               {"principal", thought->request.principal},
               {"instruction", thought->input.instruction},
               {"action", answer_body["action"]},
               {"request", answer_body["request"]},
               {"brain", answer_body["brain"]},
               {"reason", reason},
               {"expires_at_ms", expires},
               {"on_timeout", approve_on_timeout ? "approve" : "deny"}};
  if (answer_body.contains("confidence")) summary["confidence"] = answer_body["confidence"];
  const std::string id = thought->id;
  auto decide = [this, thought, answer_body, action](HitlQueue::Decision decision, const std::string& by, const std::string& why,
                                                     Reply reply) {
    Json hitl{{"state", decision_name(decision)}, {"by", by}, {"reason", why}, {"decided_at_ms", ctx_.clock().wall_ms()}};
    if (decision == HitlQueue::Decision::Approve) {
      ++counters_.approved;
      thoughts_.update(thought->id, {{"state", "approved"}, {"hitl", hitl}});
      ctx_.log().info("thought ", thought->id, ": approved by '", by.empty() ? "the timeout policy" : by, "'");
      dispatch(thought, answer_body, action, [this, thought, hitl, reply](Response r) {
        thoughts_.update(
            thought->id,
            {{"state", dispatched_state(r)}, {"status", r.status}, {"result", bounded_json(r.body.value("result", Json()))}});
        ctx_.publish_status(status());
        if (!reply) return;
        if (caller_unauthorized(r.body)) r = caller_refused(std::move(r), thought->request.principal);
        r.body["hitl"] = hitl;
        reply(std::move(r));
      });
      return;
    }
    ++counters_.denied;
    const std::string state = decision == HitlQueue::Decision::Deny      ? "denied"
                              : decision == HitlQueue::Decision::Timeout ? "timed_out"
                                                                         : "cancelled";
    thoughts_.update(thought->id, {{"state", state}, {"hitl", hitl}});
    ctx_.publish_status(status());
    ctx_.log().info("thought ", thought->id, ": ", decision_name(decision), by.empty() ? "" : " by '" + by + "'",
                    "; nothing was dispatched");
    if (reply) reply(Response::ok({{"thought_id", thought->id}, {"dispatched", false}, {"hitl", hitl}}));
  };
  const bool privileged = static_cast<int>(thought->request.role) >= static_cast<int>(sdk::Role::Owner);
  if (const auto admitted = hitl_.add(id, summary, decide, thought->epoch, thought->request.principal, privileged);
      admitted != HitlQueue::Admission::Added) {
    answer(*thought, "refused", hitl_refusal(admitted, hitl_.limits(), answer_body, reason), {{"Retry-After", "5"}});
    return;
  }
  ++counters_.held;
  const auto timer = timer_.schedule(timeout, [this, id, approve_on_timeout, timeout] {
    auto taken = hitl_.take(id);
    if (!taken) return;
    const std::string why = "no decision within " + std::to_string(timeout.count()) + " ms";
    taken->decide(approve_on_timeout ? HitlQueue::Decision::Approve : HitlQueue::Decision::Timeout, "", why, nullptr);
  });
  if (!hitl_.set_timer(id, timer)) timer_.cancel(timer);
  thoughts_.update(id, {{"hitl", {{"state", "pending"}, {"reason", reason}, {"expires_at_ms", expires}}}});
  ctx_.log().info("thought ", id, ": ", answer_body.value("raw_text", ""), " waits for approval (", reason, ", ", timeout.count(),
                  " ms)");
  Json body = answer_body;
  body["hitl"] = {{"state", "pending"},
                  {"reason", reason},
                  {"expires_in_ms", timeout.count()},
                  {"on_timeout", approve_on_timeout ? "approve" : "deny"},
                  {"authorize", "POST /api/hitl/authorize {\"thought_id\", \"decision\": \"approve\" | \"deny\"}"}};
  answer(*thought, "pending_approval", Response{202, std::move(body)});
}

void Chat::authorize(const sdk::Request& request, const std::shared_ptr<sdk::StreamWriter>& writer) {
  const auto refuse = [&writer](const Response& r) { writer->respond(r); };
  if (static_cast<int>(request.role) < static_cast<int>(sdk::Role::Owner))
    return refuse(Response::error(403, "FORBIDDEN", "approving a brain's action needs the OWNER role or higher"));
  sdk::BodyReader in(request.body, "{\"thought_id\", \"decision\": \"approve\" | \"deny\", \"reason\"?}");
  const auto id = in.string("thought_id", sdk::Field::Required, 64, /*non_empty=*/true);
  const auto decision = in.one_of("decision", {"approve", "deny"}, sdk::Field::Required);
  const auto why = in.string("reason", sdk::Field::Optional, 500);
  if (in.error()) return refuse(*in.error());
  auto taken = hitl_.take(*id);
  if (!taken) {
    const auto known = is_thought_id(*id) ? thoughts_.get(*id, false) : std::nullopt;
    if (known)
      return refuse(Response::error(409, "NOT_PENDING", "this thought is not waiting for approval",
                                    Json{{"thought_id", *id}, {"state", known->value("state", "")}}));
    return refuse(Response::error(404, "NOT_FOUND", "no thought waits under this id", Json{{"field", "thought_id"}}));
  }
  timer_.cancel(taken->timer);
  taken->decide(*decision == "approve" ? HitlQueue::Decision::Approve : HitlQueue::Decision::Deny, request.principal,
                why.value_or(""), [writer](const Response& r) { writer->respond(r); });
}

Response Chat::thought(const sdk::Request& request) const {
  const std::string id = request.path.size() > kThoughtsPrefix.size() ? request.path.substr(kThoughtsPrefix.size()) : "";
  // The reasoning may quote the prompt and what others asked: only for callers whose credential grants scope config
  // (its scopes, not its role: an OWNER JWT narrowed to status and control has no config).
  const auto found = is_thought_id(id) ? thoughts_.get(id, request.has_scope(sdk::Scope::Config)) : std::nullopt;
  if (!found)
    return Response::error(
        404, "NOT_FOUND",
        "no such thought (ids look like th-0123456789abcdef; the last " + std::to_string(thoughts_.capacity()) + " are kept)",
        Json{{"thought_id", sdk::bounded_text(id)}});  // the caller's path, quoted back
  return Response::ok(*found);
}

Response Chat::pending(const sdk::Request&) const { return Response::ok({{"pending", hitl_.list()}}); }

void Chat::dispatch(const std::shared_ptr<Thought>& thought, const Json& answer_body, const CheckedAction& action, Reply reply) {
  const auto* dispatcher = sdk::find<sdk::RequestDispatcher>(ctx_);
  if (dispatcher == nullptr) {
    reply(refusal(503, "UNAVAILABLE", "this rcand offers no request dispatcher", answer_body));
    return;
  }
  sdk::Request request;
  request.method = action.method;
  request.path = action.path;
  request.body = action.body;
  request.principal = thought->request.principal;
  request.role = thought->request.role;
  request.scopes = thought->request.scopes;
  // The caller's own credential: rcand authorizes the caller again now, so an approval that comes after the caller's
  // token was revoked (or its JWT expired, or its role was lowered) runs nothing.
  request.credential = thought->request.credential;
  request.message_id = thought->id;
  const std::string route = action.method + " " + action.path;
  auto done = [reply, answer = Json(answer_body), &log = ctx_.log(), id = thought->id, route,
               who = thought->request.principal](Response result) mutable {
    // 401/403 from rcand's own authorization: the caller no longer holds what the action needs; nothing ran.
    const bool unauthorized = caller_unauthorized(result.body);
    answer["dispatched"] = !unauthorized;
    answer["result"] = result.body;
    if (unauthorized)
      log.warn("thought ", id, ": ", route, " not run: the caller '", who, "' is no longer authorized for it (", result.status,
               ")");
    else log.info("thought ", id, ": ", route, " answered ", result.status);
    if (result.status < 300) {
      reply(Response::ok(std::move(answer)));
      return;
    }
    Json body = result.body.is_object() ? result.body : Json::object();
    body.update(answer);
    reply(Response{result.status, std::move(body)});
  };
  ++counters_.dispatched;
  ctx_.log().info("thought ", thought->id, " (message ", thought->request.message_id, ", '", thought->request.principal,
                  "'): ", route, " by ", answer_body.value("brain", ""), ": ", answer_body.value("raw_text", ""));
  if (!action.motion) {  // stops and reads are never held back by the e-stop
    dispatcher->dispatch(std::move(request), Json{{"ai", thought->ai}}, std::move(done));
    return;
  }
  std::unique_lock lock(dispatch_mutex_);
  if (epoch_.load() != thought->epoch || ctx_.estop().latched()) {
    lock.unlock();
    --counters_.dispatched;
    ++counters_.cancelled;
    reply(refusal(423, "ESTOP_ACTIVE", "the e-stop latched after this instruction came in; its action was dropped", answer_body));
    return;
  }
  dispatcher->dispatch(std::move(request), Json{{"ai", thought->ai}}, std::move(done));
}

void Chat::on_estop() noexcept {
  // The part that makes the stop safe, here on the stop path: from now on no action read before it is dispatched
  // (dispatch() checks the epoch under this lock), approved or not.
  std::uint64_t epoch;
  {
    std::lock_guard lock(dispatch_mutex_);
    epoch = ++epoch_;
  }
  // The cleanup - cancelling the brains (their sockets close), answering the waiting instructions 423, dropping the
  // waiting approvals - runs on chat's own thread kCleanupDelay later: the kernel answers the stop once every
  // on_estop() returned, and the dozen threads the cleanup wakes (brain calls, their clients) would otherwise compete
  // with that answer for the CPUs. Nothing can be dispatched meanwhile (the epoch), and the sockets still close
  // within about a millisecond of the stop.
  try {
    canceller_.schedule(kCleanupDelay, [this, epoch] { cancel_everything(epoch); });
  } catch (...) {  // no memory for the task: do it here
    cancel_everything(epoch);
  }
}

// Only what came in before the stop: an instruction sent after a quick clear is not this stop's to cancel.
void Chat::cancel_everything(std::uint64_t epoch) noexcept {
  pool_.cancel_all(epoch);
  for (auto& taken : hitl_.take_all(epoch)) {
    timer_.cancel(taken.timer);
    try {
      taken.decide(HitlQueue::Decision::Estop, "", "the e-stop latched", nullptr);
    } catch (...) {  // a log update; the others still go
    }
  }
}

void Chat::shutdown() noexcept {
  pool_.stop();
  sdk::CancelToken running;
  std::vector<sdk::TimerId> timers;
  {
    std::lock_guard lock(probes_.mutex);
    probes_.stopped = true;
    running = probes_.running;
    timers.swap(probes_.timers);
  }
  running.cancel();
  if (health_ != nullptr)
    for (const auto t : timers) health_->cancel(t);
  for (auto& taken : hitl_.take_all()) {
    timer_.cancel(taken.timer);
    try {
      taken.decide(HitlQueue::Decision::Shutdown, "", "chat shut down", nullptr);
    } catch (...) {
    }
  }
}

sdk::Json Chat::status() const {
  const auto counts = pool_.counts();
  Json brains = Json::object();
  for (const auto& b : model_brains_) brains[std::string(b->provider())] = b->describe();
  return {{"providers", settings_.providers},
          {"model", settings_.model},
          {"brains", brains},
          {"timeout_ms", settings_.timeout.count()},
          {"workers", settings_.workers},
          {"queue_limit", settings_.queue_limit},
          {"running", counts.running},
          {"queued", counts.queued},
          {"hitl_pending", hitl_.size()},
          {"thoughts", thoughts_.size()},
          {"received", counters_.received.load()},
          {"dispatched", counters_.dispatched.load()},
          {"not_understood", counters_.not_understood.load()},
          {"refused", counters_.refused.load()},
          {"injection_blocked", counters_.injection_blocked.load()},
          {"confidence_blocked", counters_.gate_blocked.load()},
          {"held_for_approval", counters_.held.load()},
          {"approved", counters_.approved.load()},
          {"denied", counters_.denied.load()},
          {"brain_failures", counters_.brain_failures.load()},
          {"busy", counters_.busy.load()},
          {"cancelled", counters_.cancelled.load()}};
}

}  // namespace rcand::plugins::chat
