// Auction-style task allocation (docs/protocol.md §11.7-§11.9) as pure logic: no threads, no I/O, no clock of its own.
// The fleet plugin's Auctions feeds it messages and the wall time and sends what it returns. Any robot can be a
// requester; every robot is a bidder.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "cost_function.hpp"

namespace rcand::plugins::fleet {

// The R2R message types the auction speaks, spelled as R2rLink::send takes them.
inline constexpr std::string_view kTaskRequest = "task_request";
inline constexpr std::string_view kTaskResponse = "task_response";
inline constexpr std::string_view kNegotiation = "negotiation";
inline constexpr std::string_view kError = "error";
// docs/protocol.md §11.3: the error codes the auction sends and reacts to.
inline constexpr int kTaskAssigned = 102;
inline constexpr int kNetworkTimeout = 104;

// A message the engine wants sent: type + payload to a target (nullopt: broadcast).
struct Outgoing {
  std::string type;
  Json payload;
  std::optional<std::string> target;
};

inline constexpr double kWinnerGraceS = 2.0;  // docs/protocol.md §11: a winner silent past bid_deadline + 2 s gets 104
inline constexpr int kMaxAuctionRounds = 5;   // re-opened at most this often before it ends as NoBids

struct Bid {
  std::string bidder;
  double cost = 0.0;
  std::vector<std::string> capabilities;
  double received_s = 0.0;
};

// ---- Requester side ----
class Auctioneer {
 public:
  enum class State { Bidding, Awarded, Assigned, NoBids };
  // Memory bounds (issue 13 #14): nothing a peer sends can grow the requester's state without limit.
  struct Limits {
    std::size_t max_auctions = 256;          // remembered auctions; beyond, the oldest decided one is forgotten
    std::size_t max_bids_per_auction = 256;  // distinct bidders per round; later ones are ignored
    std::size_t max_history = 1024;          // bid history kept per auction (repeated bids beyond it are not logged)
  };
  Auctioneer() = default;
  explicit Auctioneer(Limits limits) : limits_(limits) {}

  // Opens an auction: the task_request broadcast (with bid_deadline = now_s + bid_window_s). A task_id already
  // open is re-opened from scratch.
  std::vector<Outgoing> open(const TaskSpec& task, double bid_window_s, double now_s);
  // A negotiation bid; ignored unless the auction is bidding, the bidder has not been excluded, and it has every
  // required capability (a bid without them is not a valid bid). A repeated bid replaces the earlier one.
  void on_bid(const std::string& task_id, Bid bid);
  // The winner's task_response. Accepted: assigned. Declined: the next lowest bid is awarded (or re-opened).
  std::vector<Outgoing> on_task_response(const std::string& from, const std::string& task_id, bool accepted,
                                         std::optional<double> estimated_time, double now_s);
  // An `error` about the task from its awardee (102: assigned elsewhere) is a decline. `task_id` comes from the
  // error payload's rcand extension field "task_id".
  std::vector<Outgoing> on_error(const std::string& from, const std::string& task_id, double now_s);
  // Awards at bid_deadline; detects a silent winner at bid_deadline + 2 s (104 to it, re-open without it).
  std::vector<Outgoing> tick(double now_s);

  bool knows(const std::string& task_id) const { return auctions_.contains(task_id); }
  std::size_t size() const noexcept { return auctions_.size(); }
  // When tick() next has something to do: the earliest bid deadline of an auction still bidding or award deadline of
  // one awarded (wall seconds); nullopt when every auction is decided.
  std::optional<double> next_deadline() const noexcept;
  // {"task_id","state","round","bid_deadline","winner","estimated_time","excluded":[],"bids":[{bidder,cost,...}]}
  std::optional<Json> result(const std::string& task_id) const;
  Json results() const;
  static std::string_view state_name(State state) noexcept;

 private:
  struct Auction {
    TaskSpec task;
    double opened_s = 0.0;
    double bid_window_s = 1.0;
    double bid_deadline = 0.0;
    State state = State::Bidding;
    int round = 1;
    std::map<std::string, Bid> bids;  // this round's, by bidder
    std::vector<Json> history;        // every bid of every round, for the result
    double award_deadline = 0.0;
    std::set<std::string> excluded;  // silent or declining winners
    std::optional<std::string> winner;
    std::optional<double> estimated_time;
  };
  std::vector<Outgoing> award_next(Auction& auction, double now_s);
  std::vector<Outgoing> reopen(Auction& auction, double now_s);
  static Json request_payload(const Auction& auction);
  void evict_beyond_limit(const std::string& keep);

  Limits limits_;
  std::map<std::string, Auction> auctions_;
};

// ---- Bidder side ----
class Bidder {
 public:
  struct Held {
    std::string requester;
    double estimated_time = 0.0;
    double accepted_s = 0.0;
    double expires_s = 0.0;  // released by prune() after this (the task's deadline, or accepted + held_task_ttl_s)
  };
  // Memory bounds (issue 13 #14): a task_request or award flood cannot grow the bidder's state without limit.
  struct Limits {
    std::size_t max_held_tasks = 64;      // beyond: direct requests and awards are declined ("this robot is full")
    double held_task_ttl_s = 3600.0;      // a held task nobody completes is released after this (or at its deadline)
    std::size_t max_pending_bids = 1024;  // bids awaiting an award; beyond, the one forgotten soonest goes first
    double max_bid_horizon_s = 300.0;     // a task_request whose bid_deadline is further away than this gets no bid
  };
  Bidder() = default;
  explicit Bidder(Limits limits) : limits_(limits) {}
  struct Context {
    const std::vector<std::string>& capabilities;  // this robot's
    const CostFunction& cost;
    const std::optional<FleetPose>& position;  // fleet frame
    double now_s = 0.0;
  };

  // An auction's task_request from `requester`: the bid (negotiation to the requester) when every required
  // capability is among ours, the task is not held from another requester, and the cost function gives a cost;
  // nothing otherwise. Remembered until bid_deadline + a minute, so the award can be accepted.
  std::optional<Outgoing> on_task_request(const std::string& requester, const TaskSpec& task, double bid_deadline,
                                          const Context& context);
  // A task_request without bid_deadline (a direct request): task_response accepted with estimated_time (and the
  // task held) when capable, declined with a reason otherwise; error 102 when held from another requester.
  Outgoing on_direct_request(const std::string& requester, const TaskSpec& task, const Json& request_header,
                             const Context& context);
  // An award: task_response accepted with estimated_time; the same award again is answered the same way; an award
  // for a task held from another requester gets error 102; an award for a task never bid on is declined.
  Outgoing on_award(const std::string& requester, const std::string& task_id, const Json& award_header, double now_s);
  // The requester withdrew, or timed us out (104): forget the bid; a task held from that requester is released.
  void on_withdraw(const std::string& requester, const std::string& task_id);
  // The local robot finished (or gave up) a held task. False when it did not hold it.
  bool release(const std::string& task_id);
  // Forgets bids whose auction ended long ago.
  void prune(double now_s);

  std::size_t queue_length() const { return held_.size(); }
  std::size_t pending_bids() const { return bids_.size(); }
  const std::map<std::string, Held>& held() const { return held_; }

 private:
  Outgoing assigned_elsewhere(const std::string& requester, const std::string& task_id, const Json& header) const;
  struct PendingBid {
    double cost = 0.0;
    double forget_after_s = 0.0;
    std::optional<double> deadline;  // the task's
  };
  double held_expiry(std::optional<double> deadline, double now_s) const;
  Limits limits_;
  std::map<std::pair<std::string, std::string>, PendingBid> bids_;  // (requester, task_id)
  std::map<std::string, Held> held_;                                // by task_id
};

}  // namespace rcand::plugins::fleet
