#include "auctions.hpp"

#include <rcand/sdk/bounded_text.hpp>

#include <cmath>
#include <exception>
#include <utility>

namespace rcand::plugins::fleet {
namespace {

std::optional<FleetPoint> point_in(const Json& payload, const char* key) {
  const auto it = payload.find(key);
  if (it == payload.end() || !it->is_object()) return std::nullopt;
  return FleetPoint{it->value("x", 0.0), it->value("y", 0.0)};
}

// A task_request payload (validated by rcand before it reached the link) as a task.
TaskSpec task_of_request(const Json& p) {
  TaskSpec task;
  task.task_id = p.at("task_id").get<std::string>();
  if (const auto it = p.find("description"); it != p.end() && it->is_string()) task.description = it->get<std::string>();
  if (const auto it = p.find("deadline"); it != p.end() && it->is_number()) task.deadline = it->get<double>();
  if (const auto it = p.find("required_capabilities"); it != p.end() && it->is_array())
    task.required_capabilities = it->get<std::vector<std::string>>();
  task.location = point_in(p, "location");
  return task;
}

// The task of POST /api/r2r/auction; an error names the field.
std::variant<TaskSpec, sdk::Response> task_of_body(const Json& body) {
  TaskSpec task;
  if (!body.is_object()) return sdk::Response::bad_request("body", "body must be a JSON object");
  if (body.contains("task_id")) {
    if (!body["task_id"].is_string()) return sdk::Response::bad_request("task_id", "task_id must be a string");
    task.task_id = body["task_id"].get<std::string>();
  }
  if (body.contains("description")) {
    if (!body["description"].is_string()) return sdk::Response::bad_request("description", "description must be a string");
    task.description = body["description"].get<std::string>();
  }
  if (body.contains("deadline") && !body["deadline"].is_null()) {
    if (!body["deadline"].is_number()) return sdk::Response::bad_request("deadline", "deadline must be Unix seconds");
    task.deadline = body["deadline"].get<double>();
  }
  if (body.contains("required_capabilities")) {
    const auto& caps = body["required_capabilities"];
    if (!caps.is_array())
      return sdk::Response::bad_request("required_capabilities", "required_capabilities must be an array of strings");
    for (const auto& cap : caps) {
      if (!cap.is_string())
        return sdk::Response::bad_request("required_capabilities", "required_capabilities must be an array of strings");
      task.required_capabilities.push_back(cap.get<std::string>());
    }
  }
  if (body.contains("location") && !body["location"].is_null()) {
    const auto& at = body["location"];
    if (!at.is_object() || !at.contains("x") || !at.contains("y") || !at["x"].is_number() || !at["y"].is_number() ||
        !std::isfinite(at["x"].get<double>()) || !std::isfinite(at["y"].get<double>()))
      return sdk::Response::bad_request("location", "location must be {\"x\": number, \"y\": number} in the fleet frame");
    task.location = FleetPoint{at["x"].get<double>(), at["y"].get<double>()};
  }
  return task;
}

// How POST /api/r2r/auction waits: `wait` (default true) and `timeout_ms` (1..120000), or the answer refusing them.
std::variant<std::optional<std::chrono::milliseconds>, sdk::Response> wait_of_body(const Json& body) {
  bool wait = true;
  std::chrono::milliseconds timeout = Auctions::kDefaultWait;
  if (body.contains("wait")) {
    if (!body["wait"].is_boolean()) return sdk::Response::bad_request("wait", "wait must be true or false");
    wait = body["wait"].get<bool>();
  }
  if (body.contains("timeout_ms")) {
    const auto& value = body["timeout_ms"];
    if (!value.is_number_integer() || value.get<long long>() < 1 || value.get<long long>() > Auctions::kMaxWait.count())
      return sdk::Response::bad_request("timeout_ms", "timeout_ms must be an integer from 1 to 120000");
    timeout = std::chrono::milliseconds(value.get<long long>());
  }
  if (!wait) return std::optional<std::chrono::milliseconds>();
  return std::optional<std::chrono::milliseconds>(timeout);
}

// What an answer to `message` echoes of its header (docs/protocol.md §11.11): the link hands plugins the seed's
// header fields it parsed, so `ref` carries timestamp, source_id and target_id.
Json ref_of(const sdk::R2rMessage& message) {
  Json ref{{"timestamp", message.timestamp}, {"source_id", message.source_id}};
  if (message.target_id) ref["target_id"] = *message.target_id;
  return ref;
}

}  // namespace

Auctions::Auctions(Deps deps)
    : deps_(std::move(deps)),
      default_cost_(trip_time_cost(deps_.trips, deps_.settings.cost)),
      auctioneer_(deps_.settings.auctioneer),
      bidder_(deps_.settings.bidder) {}

Auctions::~Auctions() { unsubscribe(); }

void Auctions::subscribe() {
  // Each handler on the link's worker. A payload rcand validated can still surprise the logic (a null where a
  // string was optional): that message is dropped and logged, and the plugin keeps running.
  auto guarded = [this](void (Auctions::*handler)(const sdk::R2rMessage&)) {
    return [this, handler](const sdk::R2rMessage& message) {
      try {
        (this->*handler)(message);
      } catch (const std::exception& e) {
        if (deps_.log != nullptr) deps_.log->warn("dropped a ", message.type, " from '", message.source_id, "': ", e.what());
      }
    };
  };
  subscriptions_.push_back(deps_.link.subscribe(kTaskRequest, guarded(&Auctions::on_task_request)));
  subscriptions_.push_back(deps_.link.subscribe(kNegotiation, guarded(&Auctions::on_negotiation)));
  subscriptions_.push_back(deps_.link.subscribe(kTaskResponse, guarded(&Auctions::on_task_response)));
  subscriptions_.push_back(deps_.link.subscribe(kError, guarded(&Auctions::on_error)));
}

void Auctions::unsubscribe() noexcept {
  for (const std::uint64_t id : subscriptions_) deps_.link.unsubscribe(id);
  subscriptions_.clear();
}

Bidder::Context Auctions::bid_context(const std::optional<FleetPose>& position) const {
  return {deps_.settings.capabilities, override_cost_ ? override_cost_ : default_cost_, position, now_s()};
}

void Auctions::on_task_request(const sdk::R2rMessage& message) {
  const TaskSpec task = task_of_request(message.payload);
  // Read outside the lock: the pose source is another plugin's.
  const std::optional<FleetPose> position = deps_.position ? deps_.position() : std::nullopt;
  std::vector<Outgoing> out;
  {
    std::lock_guard lock(mutex_);
    const Bidder::Context context = bid_context(position);
    if (const auto deadline = message.payload.find("bid_deadline"); deadline != message.payload.end()) {
      if (auto bid = bidder_.on_task_request(message.source_id, task, deadline->get<double>(), context))
        out.push_back(std::move(*bid));
    } else {
      out.push_back(bidder_.on_direct_request(message.source_id, task, ref_of(message), context));
    }
  }
  send(out);
}

void Auctions::on_negotiation(const sdk::R2rMessage& message) {
  const Json& p = message.payload;
  const std::string task_id = p.at("task_id").get<std::string>();
  const std::string action = p.at("action").get<std::string>();
  std::vector<Outgoing> out;
  {
    std::lock_guard lock(mutex_);
    if (action == "bid") {
      Bid bid{message.source_id, p.at("cost").get<double>(), p.value("capabilities", std::vector<std::string>{}), now_s()};
      auctioneer_.on_bid(task_id, std::move(bid));
    } else if (action == "award") {
      out.push_back(bidder_.on_award(message.source_id, task_id, ref_of(message), now_s()));
    } else {
      bidder_.on_withdraw(message.source_id, task_id);
    }
  }
  send(out);
}

void Auctions::on_task_response(const sdk::R2rMessage& message) {
  const Json& p = message.payload;
  std::optional<double> estimate;
  if (const auto it = p.find("estimated_time"); it != p.end() && it->is_number()) estimate = it->get<double>();
  std::vector<Outgoing> out;
  {
    std::lock_guard lock(mutex_);
    out = auctioneer_.on_task_response(message.source_id, p.at("task_id").get<std::string>(), p.at("accepted").get<bool>(),
                                       estimate, now_s());
  }
  send(out);
  answer_decided();
  due_changed();  // an award answered or declined: the next award's deadline
}

// 102 from an awardee is a decline; 104 from a requester withdraws the award (rcand logs every error it receives).
void Auctions::on_error(const sdk::R2rMessage& message) {
  const Json& p = message.payload;
  const auto task = p.find("task_id");
  if (task == p.end() || !task->is_string()) return;
  const int code = p.at("code").get<int>();
  std::vector<Outgoing> out;
  {
    std::lock_guard lock(mutex_);
    if (code == kTaskAssigned) out = auctioneer_.on_error(message.source_id, task->get<std::string>(), now_s());
    if (code == kNetworkTimeout) bidder_.on_withdraw(message.source_id, task->get<std::string>());
  }
  send(out);
  answer_decided();
  due_changed();  // an award answered or declined: the next award's deadline
}

void Auctions::tick() {
  std::vector<Outgoing> out;
  {
    std::lock_guard lock(mutex_);
    const double now = now_s();
    out = auctioneer_.tick(now);
    bidder_.prune(now);
  }
  send(out);
  answer_decided();
}

std::chrono::microseconds Auctions::until_due(std::chrono::microseconds idle) const {
  std::lock_guard lock(mutex_);
  double due_us = static_cast<double>(idle.count());
  if (const auto deadline = auctioneer_.next_deadline()) due_us = std::min(due_us, (*deadline - now_s()) * 1e6);
  const std::int64_t now = deps_.clock.now_us();
  for (const Waiter& waiter : waiters_) due_us = std::min(due_us, static_cast<double>(waiter.deadline_us - now));
  return std::chrono::microseconds(static_cast<std::int64_t>(std::max(due_us, 0.0)));
}

void Auctions::due_changed() const {
  if (deps_.due_changed) deps_.due_changed();
}

void Auctions::send(const std::vector<Outgoing>& messages) {
  for (const Outgoing& message : messages) {
    const sdk::R2rSendResult sent = deps_.link.send(message.type, message.payload, message.target);
    if (!sent.ok && deps_.log != nullptr)
      deps_.log->warn("could not send ", message.type, message.target ? " to '" + *message.target + "'" : std::string(), ": ",
                      sent.error);
  }
}

std::variant<std::string, sdk::R2rSendResult> Auctions::open_auction(TaskSpec task) {
  std::vector<Outgoing> out;
  {
    std::lock_guard lock(mutex_);
    if (task.task_id.empty())
      task.task_id =
          deps_.settings.robot_name + "-" + std::to_string(deps_.clock.wall_ms()) + "-" + std::to_string(++task_counter_);
    out = auctioneer_.open(task, deps_.settings.bid_window_s, now_s());
  }
  for (const Outgoing& message : out) {
    sdk::R2rSendResult sent = deps_.link.send(message.type, message.payload, message.target);
    if (!sent.ok) return sent;  // a field the seed's rules refuse ("/payload/required_capabilities/0")
  }
  due_changed();
  return task.task_id;
}

std::optional<Json> Auctions::auction_result(const std::string& task_id) const {
  std::lock_guard lock(mutex_);
  return auctioneer_.result(task_id);
}

Json Auctions::held_tasks() const {
  std::lock_guard lock(mutex_);
  Json tasks = Json::array();
  for (const auto& [task_id, held] : bidder_.held())
    tasks.push_back({{"task_id", task_id},
                     {"requester", held.requester},
                     {"estimated_time", held.estimated_time},
                     {"accepted_s", held.accepted_s}});
  return tasks;
}

std::size_t Auctions::tasks_held() const {
  std::lock_guard lock(mutex_);
  return bidder_.queue_length();
}

std::size_t Auctions::auctions() const {
  std::lock_guard lock(mutex_);
  return auctioneer_.size();
}

bool Auctions::complete_task(const std::string& task_id) {
  std::lock_guard lock(mutex_);
  return bidder_.release(task_id);
}

void Auctions::set_cost_override(sdk::R2rCostFunction cost) {
  CostFunction wrapped = cost ? plugin_cost(std::move(cost), deps_.log) : CostFunction{};
  std::lock_guard lock(mutex_);
  override_cost_ = std::move(wrapped);
}

// ---- POST /api/r2r/auction: open, then answer at once or when decided ----

void Auctions::open_for_request(const Json& body, const sdk::FleetAuctions::Answer& answer) {
  auto task = task_of_body(body);
  if (auto* refused = std::get_if<sdk::Response>(&task)) return answer(*refused);
  auto wait = wait_of_body(body);
  if (auto* refused = std::get_if<sdk::Response>(&wait)) return answer(*refused);
  auto opened = open_auction(std::get<TaskSpec>(std::move(task)));
  if (auto* refused = std::get_if<sdk::R2rSendResult>(&opened))
    return answer(sdk::Response::bad_request(refused->field.empty() ? "body" : refused->field, refused->error));
  const std::string& task_id = std::get<std::string>(opened);
  const auto timeout = std::get<std::optional<std::chrono::milliseconds>>(wait);
  if (!timeout) return answer(sdk::Response{202, {{"task_id", task_id}, {"state", "bidding"}}});
  wait_for(task_id, *timeout, answer);
}

void Auctions::wait_for(const std::string& task_id, std::chrono::milliseconds timeout, sdk::FleetAuctions::Answer answer) {
  {
    std::lock_guard lock(mutex_);
    if (!abandoned_) {
      const std::int64_t now = deps_.clock.now_us();
      waiters_.push_back({task_id, now, now + std::chrono::microseconds(timeout).count(), std::move(answer)});
      answer = nullptr;
    }
  }
  if (answer) return answer(sdk::Response::error(503, "UNAVAILABLE", "rcand is shutting down"));
  due_changed();
}

void Auctions::answer_decided() {
  std::vector<std::pair<sdk::FleetAuctions::Answer, Json>> ready;
  {
    std::lock_guard lock(mutex_);
    const std::int64_t now = deps_.clock.now_us();
    for (auto it = waiters_.begin(); it != waiters_.end();) {
      Json result = auctioneer_.result(it->task_id).value_or(Json::object());
      const std::string state = result.value("state", "");
      const bool decided = state == "assigned" || state == "no_bids";
      if (!decided && now < it->deadline_us) {
        ++it;
        continue;
      }
      result["decided"] = decided;
      result["elapsed_ms"] = static_cast<double>(now - it->started_us) / 1000.0;
      ready.emplace_back(std::move(it->answer), std::move(result));
      it = waiters_.erase(it);
    }
  }
  for (auto& [answer, result] : ready) answer(sdk::Response::ok(std::move(result)));
}

void Auctions::abandon_waiting() noexcept {
  std::vector<Waiter> abandoned;
  {
    std::lock_guard lock(mutex_);
    abandoned_ = true;
    abandoned.swap(waiters_);
  }
  for (auto& waiter : abandoned) {
    try {
      waiter.answer(sdk::Response::error(503, "UNAVAILABLE", "rcand is shutting down"));
    } catch (...) {  // the caller went away
    }
  }
}

// ---- the service rcand finds: noexcept at the boundary, as services.hpp asks ----

void Auctions::Service::open(const Json& body, Answer answer) const noexcept {
  try {
    auctions_.open_for_request(body, answer);
  } catch (const std::exception& e) {
    try {
      answer(sdk::Response::error(500, "INTERNAL", std::string("the auction failed: ") + e.what()));
    } catch (...) {
    }
  }
}

sdk::Response Auctions::Service::result(std::string_view task_id) const noexcept {
  try {
    if (auto result = auctions_.auction_result(std::string(task_id))) return sdk::Response::ok(std::move(*result));
    return sdk::Response::error(404, "NOT_FOUND", "this robot never opened an auction '" + sdk::bounded_text(task_id) + "'");
  } catch (...) {
    return {500, nullptr};
  }
}

Json Auctions::Service::held_tasks() const noexcept {
  try {
    return auctions_.held_tasks();
  } catch (...) {
    return Json::array();
  }
}

std::size_t Auctions::Service::tasks_held() const noexcept {
  try {
    return auctions_.tasks_held();
  } catch (...) {  // std::mutex::lock may throw std::system_error
    return 0;
  }
}

void Auctions::Service::set_cost_override(sdk::R2rCostFunction cost) const noexcept {
  try {
    auctions_.set_cost_override(std::move(cost));
  } catch (...) {  // no memory for the copy: the previous price stays
  }
}

}  // namespace rcand::plugins::fleet
