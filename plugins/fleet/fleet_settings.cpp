#include "fleet_settings.hpp"

#include <cstdint>

namespace rcand::plugins::fleet {

FleetSettings read_fleet_settings(const sdk::ConfigView& robot_config) {
  FleetSettings s;
  s.robot_name = robot_config.get_or<std::string>("metadata.robot_name", "");
  const sdk::ConfigView protocol = robot_config.sub("rcan_protocol");
  if (const auto listed = protocol.raw().find("capabilities"); listed != protocol.raw().end() && listed->is_array())
    for (const auto& name : *listed)
      if (name.is_string()) s.capabilities.push_back(name.get<std::string>());
  const sdk::ConfigView r2r = robot_config.sub("runtime.r2r");
  s.origin = {r2r.get_or("origin.x", 0.0), r2r.get_or("origin.y", 0.0), r2r.get_or("origin.heading_deg", 0.0)};
  s.bid_window_s = static_cast<double>(r2r.get_or<std::int64_t>("bid_window_ms", 1000)) / 1000.0;
  s.cost.seconds_per_task = r2r.get_or("cost_per_queued_task_s", 30.0);
  s.bidder.max_held_tasks = static_cast<std::size_t>(r2r.get_or<std::int64_t>("max_held_tasks", 64));
  return s;
}

}  // namespace rcand::plugins::fleet
