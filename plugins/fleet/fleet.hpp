// The fleet capability (org.rcand.fleet): R2R task auctions (docs/protocol.md §11.7-§11.9) as a plugin. rcand keeps
// the R2R transports, authentication and validation; this plugin speaks the auction over its R2rLink, prices bids
// with the TripEstimator it finds (nav's) from the PoseSource's pose placed by runtime.r2r.origin, and offers
// sdk::FleetAuctions, through which rcand serves /api/r2r/auction*. Declared by itself when runtime.r2r.enabled is
// true (its manifest's "declared_when"); idle when the robot has no R2R.
#pragma once

#include <rcand/sdk/plugin.hpp>

#include <atomic>
#include <memory>
#include <optional>

#include "auctions.hpp"

namespace rcand::plugins::fleet {

class Fleet final : public sdk::Capability {
 public:
  // Ticks come when a deadline is due (Auctions::until_due) and at least this often, for the published status and
  // forgetting expired bids: a 20 ms poll cost an idle robot ~0.25 % of a core, half a core for a fleet of 200.
  static constexpr std::chrono::milliseconds kIdleTickPeriod{250};

  explicit Fleet(sdk::PluginContext& ctx) : ctx_(ctx) {}
  ~Fleet() override;

  // Reads the settings (throws sdk::ConfigError naming the key), subscribes, starts the ticks on the worker "r2r" and
  // offers the FleetAuctions service.
  void start() override;
  std::vector<sdk::Route> routes() override { return {}; }  // rcand's R2R service serves the auction endpoints
  sdk::Json status() const override;
  void shutdown() noexcept override;

  // The robot in the fleet frame: the PoseSource's pose placed by runtime.r2r.origin. Without a pose source, a robot
  // that has no nav stays at its origin (as its R2R status says) and one whose nav is not running does not know.
  std::optional<FleetPose> position() const;
  Auctions* auctions() noexcept { return auctions_.get(); }

 private:
  void tick();         // on the worker "r2r"; schedules the next one
  void tick_sooner();  // any thread: a deadline may now come before the next tick

  sdk::PluginContext& ctx_;
  FleetSettings settings_;
  std::unique_ptr<sdk::R2rLink> link_;  // from sdk::R2rLinks; null while the robot has no R2R. Outlives auctions_
  std::unique_ptr<Auctions> auctions_;  // null while the robot has no R2R
  sdk::Worker* worker_ = nullptr;
  sdk::TimerId next_tick_ = 0;  // worker "r2r" only
  std::atomic<bool> stopping_{false};
  sdk::Json published_;  // the status last published (worker "r2r" only)
};

}  // namespace rcand::plugins::fleet
