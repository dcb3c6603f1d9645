// One robot's auctions (docs/protocol.md §11.7-§11.9) over its R2rLink: as requester it opens auctions (POST
// /api/r2r/auction, through the sdk::FleetAuctions service), collects bids and awards the lowest; as bidder it prices
// others' task requests, bids, and holds the tasks it is awarded. The pure logic is auction.hpp; this class feeds it
// the link's messages and the wall clock and sends what it returns.
//
// Threads: the link's callbacks run on the link's worker ("r2r"), tick() wherever its owner calls it (the plugin: that
// same worker, at the next deadline, until_due()), the service methods on any thread (rcand's HTTP and R2R threads). One mutex
// guards the state, held briefly and never while sending: R2rLink::send may hand the message to a transport at once.
#pragma once

#include <rcand/sdk/clock.hpp>
#include <rcand/sdk/interfaces/fleet_auctions.hpp>
#include <rcand/sdk/logger.hpp>
#include <rcand/sdk/r2r.hpp>

#include <chrono>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "auction.hpp"
#include "cost_function.hpp"
#include "fleet_settings.hpp"

namespace rcand::plugins::fleet {

class Auctions {
 public:
  struct Deps {
    sdk::R2rLink& link;
    const sdk::Clock& clock;
    FleetSettings settings;
    std::function<std::optional<FleetPose>()> position;  // the robot in the fleet frame; empty or nullopt: unknown
    TripEstimatorLookup trips;                           // what the default price times trips with
    sdk::Logger* log = nullptr;                          // null: silent
    // Called (any thread, never under the lock) when a deadline may have come nearer than the next tick: an auction
    // opened, a request waiting, an award answered. Empty: the owner ticks on its own schedule.
    std::function<void()> due_changed;
  };
  static constexpr std::chrono::milliseconds kDefaultWait{30'000};  // POST /api/r2r/auction's timeout_ms
  static constexpr std::chrono::milliseconds kMaxWait{120'000};

  explicit Auctions(Deps deps);
  ~Auctions();  // unsubscribe()
  Auctions(const Auctions&) = delete;
  Auctions& operator=(const Auctions&) = delete;

  // Subscribes to task_request, negotiation, task_response and error on the link. Throws what the link throws.
  void subscribe();
  void unsubscribe() noexcept;
  // Award at bid deadlines, 104 to silent winners, forget expired bids and held tasks, answer decided requests.
  void tick();
  // How long until tick() next has a deadline to meet (an auction's bid or award deadline, a waiting request's
  // timeout); `idle` when there is none sooner.
  std::chrono::microseconds until_due(std::chrono::microseconds idle) const;
  // Shutdown: every request still waiting for its auction is answered 503 (rcand is shutting down).
  void abandon_waiting() noexcept;

  // Opens an auction for `task` (its task_request goes out with bid_deadline = now + the bid window). An empty
  // task_id is generated ("<robot>-<wall ms>-<n>"). The task id, or why the link refused the request (field set when
  // the task was at fault).
  std::variant<std::string, sdk::R2rSendResult> open_auction(TaskSpec task);
  // The auction's state and all bids, or nullopt when this robot never opened it.
  std::optional<Json> auction_result(const std::string& task_id) const;
  // The tasks this robot holds ({"task_id","requester","estimated_time","accepted_s"}); releasing one when done.
  Json held_tasks() const;
  std::size_t tasks_held() const;
  bool complete_task(const std::string& task_id);
  std::size_t auctions() const;
  // A plugin's price (R2rLink::set_cost_function, handed on by rcand); empty restores the default.
  void set_cost_override(sdk::R2rCostFunction cost);

  // What rcand's R2R service finds (sdk::find<sdk::FleetAuctions>); offer it while this object lives.
  const sdk::FleetAuctions& service() const noexcept { return service_; }

 private:
  class Service final : public sdk::FleetAuctions {
   public:
    explicit Service(Auctions& auctions) : auctions_(auctions) {}
    void open(const Json& body, Answer answer) const noexcept override;
    sdk::Response result(std::string_view task_id) const noexcept override;
    Json held_tasks() const noexcept override;
    std::size_t tasks_held() const noexcept override;
    void set_cost_override(sdk::R2rCostFunction cost) const noexcept override;

   private:
    Auctions& auctions_;
  };
  struct Waiter {
    std::string task_id;
    std::int64_t started_us = 0, deadline_us = 0;
    sdk::FleetAuctions::Answer answer;
  };

  void on_task_request(const sdk::R2rMessage& message);
  void on_negotiation(const sdk::R2rMessage& message);
  void on_task_response(const sdk::R2rMessage& message);
  void on_error(const sdk::R2rMessage& message);
  void open_for_request(const Json& body, const sdk::FleetAuctions::Answer& answer);
  void wait_for(const std::string& task_id, std::chrono::milliseconds timeout, sdk::FleetAuctions::Answer answer);
  void answer_decided();
  void due_changed() const;
  void send(const std::vector<Outgoing>& messages);
  Bidder::Context bid_context(const std::optional<FleetPose>& position) const;  // requires mutex_
  double now_s() const { return static_cast<double>(deps_.clock.wall_ms()) / 1000.0; }

  Deps deps_;
  Service service_{*this};
  CostFunction default_cost_;
  std::vector<std::uint64_t> subscriptions_;

  mutable std::mutex mutex_;  // everything below
  Auctioneer auctioneer_;
  Bidder bidder_;
  CostFunction override_cost_;  // empty: default_cost_
  std::vector<Waiter> waiters_;
  std::uint64_t task_counter_ = 0;
  bool abandoned_ = false;
};

}  // namespace rcand::plugins::fleet
