// What the fleet plugin reads from the robot config. The runtime.r2r keys stay the R2R service's: its key table checks
// them (with file:line:column) before any plugin starts, so they are read here as written, with the same defaults.
#pragma once

#include <rcand/sdk/config_view.hpp>
#include <rcand/sdk/interfaces/pose_source.hpp>

#include <string>
#include <vector>

#include "auction.hpp"
#include "cost_function.hpp"

namespace rcand::plugins::fleet {

struct FleetSettings {
  std::string robot_name;                 // metadata.robot_name: generated task ids start with it
  std::vector<std::string> capabilities;  // rcan_protocol.capabilities as declared: what this robot bids with
  sdk::Pose2d origin;                     // runtime.r2r.origin: where this robot's own frame sits in the fleet frame
  double bid_window_s = 1.0;              // runtime.r2r.bid_window_ms: how long an auction this robot opens collects bids
  TripCostSettings cost;                  // runtime.r2r.cost_per_queued_task_s
  Bidder::Limits bidder;                  // runtime.r2r.max_held_tasks (64); the rest fixed
  Auctioneer::Limits auctioneer;
};

// Throws sdk::ConfigError naming the key when a value has the wrong type.
FleetSettings read_fleet_settings(const sdk::ConfigView& robot_config);

}  // namespace rcand::plugins::fleet
