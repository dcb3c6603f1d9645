// R2R task auctions as a service (rcand/sdk/services.hpp, docs/protocol.md §11.7-§11.9). The fleet plugin
// (org.rcand.fleet) offers it; rcand's R2R service finds it to serve POST /api/r2r/auction and
// GET /api/r2r/auction/<task_id>, to report the tasks this robot holds (status `tasks_held`, GET /api/r2r/peers
// `held_tasks`) and to hand on the bid price a plugin sets with R2rLink::set_cost_function. The auction itself runs
// in the plugin, on R2R messages it sends and receives through its own R2rLink. As every service (services.hpp): any
// thread, noexcept, never blocking beyond a brief lock; `open` answers later, from the plugin's worker, when it waits.
#pragma once

#include <cstddef>
#include <functional>
#include <string_view>

#include "rcand/sdk/export.hpp"
#include "rcand/sdk/http.hpp"
#include "rcand/sdk/r2r.hpp"
#include "rcand/sdk/services.hpp"

namespace rcand::sdk {

class RCAND_INTERFACE FleetAuctions {
 public:
  static constexpr std::string_view kServiceId = "rcand.fleet_auctions/1";
  // Called exactly once, from any thread, with the HTTP answer (errors in the docs/protocol.md §4 body).
  using Answer = std::function<void(const Response&)>;

  virtual ~FleetAuctions() = default;
  // POST /api/r2r/auction with its JSON body: {"task_id"?, "description"?, "required_capabilities"?, "location"?
  // {x, y}, "deadline"?, "wait"? (true), "timeout_ms"? (30000, at most 120000)}. Opens the auction at once and answers
  // 400 naming the field at fault, 202 {"task_id", "state"} when wait is false, else 200 with the result (plus
  // "decided" and "elapsed_ms") once it is decided or timeout_ms passed.
  virtual void open(const Json& body, Answer answer) const noexcept = 0;
  // GET /api/r2r/auction/<task_id>: 200 with the auction's result, 404 NOT_FOUND when this robot never opened it.
  virtual Response result(std::string_view task_id) const noexcept = 0;
  // The tasks this robot holds: [{"task_id", "requester", "estimated_time", "accepted_s"}], and how many.
  virtual Json held_tasks() const noexcept = 0;
  virtual std::size_t tasks_held() const noexcept = 0;
  // The bid price a plugin installed with R2rLink::set_cost_function; empty restores the default (trip time by
  // the TripEstimator plus the queue).
  virtual void set_cost_override(R2rCostFunction cost) const noexcept = 0;
};

}  // namespace rcand::sdk
