#include "auction.hpp"

#include <algorithm>

namespace rcand::plugins::fleet {
namespace {

using json = Json;

constexpr double kForgetBidAfterS = 60.0;

bool has_all(const std::vector<std::string>& have, const std::vector<std::string>& required) {
  return std::all_of(required.begin(), required.end(),
                     [&](const std::string& cap) { return std::find(have.begin(), have.end(), cap) != have.end(); });
}

Outgoing negotiation(const std::string& task_id, const char* action, const std::string& target) {
  return {std::string(kNegotiation), json{{"task_id", task_id}, {"action", action}}, target};
}

Outgoing task_response(const std::string& task_id, bool accepted, std::optional<double> estimated_time, const std::string& target,
                       std::string reason = {}) {
  json payload{{"task_id", task_id}, {"accepted", accepted}};
  payload["estimated_time"] = estimated_time ? json(*estimated_time) : json();
  if (!reason.empty()) payload["reason"] = std::move(reason);
  return {std::string(kTaskResponse), std::move(payload), target};
}

}  // namespace

// ---- Auctioneer ----

std::string_view Auctioneer::state_name(State state) noexcept {
  switch (state) {
    case State::Bidding: return "bidding";
    case State::Awarded: return "awarded";
    case State::Assigned: return "assigned";
    case State::NoBids: return "no_bids";
  }
  return "bidding";
}

json Auctioneer::request_payload(const Auction& a) {
  json payload = task_fields(a.task);
  payload["bid_deadline"] = a.bid_deadline;
  return payload;
}

std::vector<Outgoing> Auctioneer::open(const TaskSpec& task, double bid_window_s, double now_s) {
  Auction& a = auctions_[task.task_id];
  a = Auction{};
  a.task = task;
  a.opened_s = now_s;
  a.bid_window_s = bid_window_s;
  a.bid_deadline = now_s + bid_window_s;
  std::vector<Outgoing> out{{std::string(kTaskRequest), request_payload(a), std::nullopt}};
  evict_beyond_limit(task.task_id);
  return out;
}

void Auctioneer::evict_beyond_limit(const std::string& keep) {
  while (auctions_.size() > std::max<std::size_t>(limits_.max_auctions, 1)) {
    // The oldest decided auction goes first; when every one is still running, the oldest of those.
    auto victim = auctions_.end();
    for (bool decided_only : {true, false}) {
      for (auto it = auctions_.begin(); it != auctions_.end(); ++it) {
        if (it->first == keep) continue;
        const bool decided = it->second.state == State::Assigned || it->second.state == State::NoBids;
        if (decided_only && !decided) continue;
        if (victim == auctions_.end() || it->second.opened_s < victim->second.opened_s) victim = it;
      }
      if (victim != auctions_.end()) break;
    }
    if (victim == auctions_.end()) return;
    auctions_.erase(victim);
  }
}

void Auctioneer::on_bid(const std::string& task_id, Bid bid) {
  const auto it = auctions_.find(task_id);
  if (it == auctions_.end()) return;
  Auction& a = it->second;
  if (a.state != State::Bidding || a.excluded.contains(bid.bidder) || !has_all(bid.capabilities, a.task.required_capabilities))
    return;
  if (a.bids.size() >= limits_.max_bids_per_auction && !a.bids.contains(bid.bidder)) return;
  if (a.history.size() < limits_.max_history)
    a.history.push_back({{"round", a.round}, {"bidder", bid.bidder}, {"cost", bid.cost}, {"capabilities", bid.capabilities}});
  a.bids[bid.bidder] = std::move(bid);
}

std::vector<Outgoing> Auctioneer::award_next(Auction& a, double now_s) {
  const Bid* best = nullptr;
  for (const auto& [bidder, bid] : a.bids)  // map order: a tie keeps the lowest name
    if (!a.excluded.contains(bidder) && (best == nullptr || bid.cost < best->cost)) best = &bid;
  if (best == nullptr) {
    // Bids existed but every bidder is out: ask the fleet again; a round with no bids at all ends the auction.
    if (!a.bids.empty()) return reopen(a, now_s);
    a.state = State::NoBids;
    a.winner.reset();
    return {};
  }
  a.state = State::Awarded;
  a.winner = best->bidder;
  a.estimated_time.reset();
  a.award_deadline = std::max(now_s, a.bid_deadline) + kWinnerGraceS;
  return {negotiation(a.task.task_id, "award", best->bidder)};
}

std::vector<Outgoing> Auctioneer::reopen(Auction& a, double now_s) {
  if (a.round >= kMaxAuctionRounds) {
    a.state = State::NoBids;
    a.winner.reset();
    return {};
  }
  ++a.round;
  a.bids.clear();
  a.winner.reset();
  a.state = State::Bidding;
  a.bid_deadline = now_s + a.bid_window_s;
  return {{std::string(kTaskRequest), request_payload(a), std::nullopt}};
}

std::vector<Outgoing> Auctioneer::on_task_response(const std::string& from, const std::string& task_id, bool accepted,
                                                   std::optional<double> estimated_time, double now_s) {
  const auto it = auctions_.find(task_id);
  if (it == auctions_.end()) return {};
  Auction& a = it->second;
  if (a.state != State::Awarded || a.winner != from) return {};
  if (accepted) {
    a.state = State::Assigned;
    a.estimated_time = estimated_time;
    return {};
  }
  a.excluded.insert(from);
  return award_next(a, now_s);
}

std::vector<Outgoing> Auctioneer::on_error(const std::string& from, const std::string& task_id, double now_s) {
  return on_task_response(from, task_id, false, std::nullopt, now_s);
}

std::vector<Outgoing> Auctioneer::tick(double now_s) {
  std::vector<Outgoing> out;
  for (auto& [task_id, a] : auctions_) {
    std::vector<Outgoing> step;
    if (a.state == State::Bidding && now_s >= a.bid_deadline) {
      step = award_next(a, now_s);
    } else if (a.state == State::Awarded && now_s > a.award_deadline) {
      const std::string silent = *a.winner;
      a.excluded.insert(silent);
      json error{{"code", kNetworkTimeout},
                 {"message", "no task_response to the award of task '" + task_id + "' within " + json(kWinnerGraceS).dump() +
                                 " s of the bid deadline; re-auctioned without you"},
                 {"task_id", task_id}};
      step.push_back({std::string(kError), std::move(error), silent});
      auto reopened = reopen(a, now_s);
      step.insert(step.end(), reopened.begin(), reopened.end());
    }
    out.insert(out.end(), std::make_move_iterator(step.begin()), std::make_move_iterator(step.end()));
  }
  return out;
}

std::optional<double> Auctioneer::next_deadline() const noexcept {
  std::optional<double> next;
  for (const auto& [task_id, a] : auctions_) {
    const bool pending = a.state == State::Bidding || a.state == State::Awarded;
    const double at = a.state == State::Bidding ? a.bid_deadline : a.award_deadline;
    if (pending && (!next || at < *next)) next = at;
  }
  return next;
}

std::optional<json> Auctioneer::result(const std::string& task_id) const {
  const auto it = auctions_.find(task_id);
  if (it == auctions_.end()) return std::nullopt;
  const Auction& a = it->second;
  json doc{{"task_id", task_id},
           {"state", std::string(state_name(a.state))},
           {"round", a.round},
           {"bid_deadline", a.bid_deadline},
           {"required_capabilities", a.task.required_capabilities},
           {"winner", a.winner ? json(*a.winner) : json()},
           {"estimated_time", a.estimated_time ? json(*a.estimated_time) : json()},
           {"excluded", std::vector<std::string>(a.excluded.begin(), a.excluded.end())},
           {"bids", a.history}};
  if (a.task.location) doc["location"] = {{"x", a.task.location->x}, {"y", a.task.location->y}};
  return doc;
}

json Auctioneer::results() const {
  json all = json::array();
  for (const auto& [task_id, auction] : auctions_) all.push_back(*result(task_id));
  return all;
}

// ---- Bidder ----

std::optional<Outgoing> Bidder::on_task_request(const std::string& requester, const TaskSpec& task, double bid_deadline,
                                                const Context& context) {
  if (!has_all(context.capabilities, task.required_capabilities)) return std::nullopt;
  if (!(bid_deadline <= context.now_s + limits_.max_bid_horizon_s)) return std::nullopt;  // far off (or NaN): no bid
  if (const auto held = held_.find(task.task_id); held != held_.end() && held->second.requester != requester)
    return std::nullopt;  // already doing it for someone else
  const std::optional<double> cost = context.cost ? context.cost(CostInput{task, context.position, held_.size()}) : std::nullopt;
  if (!cost || !(*cost >= 0)) return std::nullopt;  // also refuses NaN from a plugin's cost function
  const std::pair<std::string, std::string> key{requester, task.task_id};
  if (bids_.size() >= limits_.max_pending_bids && !bids_.contains(key)) {
    prune(context.now_s);
    while (!bids_.empty() && bids_.size() >= std::max<std::size_t>(limits_.max_pending_bids, 1)) {
      const auto soonest = std::min_element(bids_.begin(), bids_.end(), [](const auto& x, const auto& y) {
        return x.second.forget_after_s < y.second.forget_after_s;
      });
      bids_.erase(soonest);
    }
  }
  bids_[key] = {*cost, std::max(bid_deadline, context.now_s) + kForgetBidAfterS, task.deadline};
  json payload{{"task_id", task.task_id}, {"action", "bid"}, {"cost", *cost}, {"capabilities", context.capabilities}};
  return Outgoing{std::string(kNegotiation), std::move(payload), requester};
}

Outgoing Bidder::assigned_elsewhere(const std::string& requester, const std::string& task_id, const json& header) const {
  json error{{"code", kTaskAssigned},
             {"message", "task '" + task_id + "' is already assigned to this robot by another requester"},
             {"ref", header},
             {"task_id", task_id}};
  return {std::string(kError), std::move(error), requester};
}

Outgoing Bidder::on_direct_request(const std::string& requester, const TaskSpec& task, const json& request_header,
                                   const Context& context) {
  if (const auto held = held_.find(task.task_id); held != held_.end()) {
    if (held->second.requester != requester) return assigned_elsewhere(requester, task.task_id, request_header);
    return task_response(task.task_id, true, held->second.estimated_time, requester);
  }
  if (!has_all(context.capabilities, task.required_capabilities))
    return task_response(task.task_id, false, std::nullopt, requester, "missing a required capability");
  prune(context.now_s);
  if (held_.size() >= limits_.max_held_tasks)
    return task_response(task.task_id, false, std::nullopt, requester, "this robot already holds as many tasks as it takes");
  const std::optional<double> cost = context.cost ? context.cost(CostInput{task, context.position, held_.size()}) : std::nullopt;
  if (!cost || !(*cost >= 0)) return task_response(task.task_id, false, std::nullopt, requester, "cannot estimate the task");
  held_[task.task_id] = {requester, *cost, context.now_s, held_expiry(task.deadline, context.now_s)};
  return task_response(task.task_id, true, *cost, requester);
}

Outgoing Bidder::on_award(const std::string& requester, const std::string& task_id, const json& award_header, double now_s) {
  prune(now_s);  // first: nothing below may hold an iterator across it
  if (const auto held = held_.find(task_id); held != held_.end()) {
    if (held->second.requester != requester) return assigned_elsewhere(requester, task_id, award_header);
    return task_response(task_id, true, held->second.estimated_time, requester);  // a repeated award
  }
  const auto bid = bids_.find({requester, task_id});
  if (bid == bids_.end()) return task_response(task_id, false, std::nullopt, requester, "this robot did not bid on the task");
  if (held_.size() >= limits_.max_held_tasks)
    return task_response(task_id, false, std::nullopt, requester, "this robot already holds as many tasks as it takes");
  held_[task_id] = {requester, bid->second.cost, now_s, held_expiry(bid->second.deadline, now_s)};
  bids_.erase(bid);
  return task_response(task_id, true, held_[task_id].estimated_time, requester);
}

void Bidder::on_withdraw(const std::string& requester, const std::string& task_id) {
  bids_.erase({requester, task_id});
  if (const auto held = held_.find(task_id); held != held_.end() && held->second.requester == requester) held_.erase(held);
}

bool Bidder::release(const std::string& task_id) { return held_.erase(task_id) > 0; }

void Bidder::prune(double now_s) {
  std::erase_if(bids_, [now_s](const auto& entry) { return entry.second.forget_after_s < now_s; });
  std::erase_if(held_, [now_s](const auto& entry) { return entry.second.expires_s < now_s; });
}

double Bidder::held_expiry(std::optional<double> deadline, double now_s) const {
  const double ttl = now_s + limits_.held_task_ttl_s;
  return deadline && *deadline > now_s ? std::min(*deadline, ttl) : ttl;
}

}  // namespace rcand::plugins::fleet
