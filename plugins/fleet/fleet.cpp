#include "fleet.hpp"

#include <algorithm>

namespace rcand::plugins::fleet {

Fleet::~Fleet() { shutdown(); }

void Fleet::start() {
  if (const auto* links = sdk::find<sdk::R2rLinks>(ctx_)) link_ = links->make_link(ctx_.worker("r2r"), "org.rcand.fleet");
  if (link_ == nullptr) {
    ctx_.log().info("no R2R on this robot (runtime.r2r.enabled is off): no auctions");
    return;
  }
  settings_ = read_fleet_settings(ctx_.robot_config());
  worker_ = &ctx_.worker("r2r");  // the link's callbacks run here too: ticks and messages never overlap
  auctions_ = std::make_unique<Auctions>(Auctions::Deps{
      .link = *link_,
      .clock = ctx_.clock(),
      .settings = settings_,
      .position = [this] { return position(); },
      .trips = [this] { return sdk::find<sdk::TripEstimator>(ctx_); },
      .log = &ctx_.log(),
      .due_changed = [this] { tick_sooner(); },
  });
  next_tick_ = worker_->schedule(kIdleTickPeriod, [this] { tick(); });  // before any message can ask for a sooner one
  auctions_->subscribe();
  if (!sdk::offer<sdk::FleetAuctions>(ctx_, auctions_->service()))
    ctx_.log().warn("another plugin already offers fleet auctions; /api/r2r/auction is served by that one");
}

void Fleet::tick() {
  if (stopping_) return;
  auctions_->tick();
  sdk::Json now{{"tasks_held", auctions_->tasks_held()}, {"auctions", auctions_->auctions()}};
  if (now != published_) {
    ctx_.publish_status(now);
    published_ = std::move(now);
  }
  // At least a millisecond: a deadline is met once it has passed.
  const auto delay = std::max<std::chrono::microseconds>(auctions_->until_due(kIdleTickPeriod), std::chrono::milliseconds(1));
  next_tick_ = worker_->schedule(delay, [this] { tick(); });
}

// The pending tick, cancelled, runs now and schedules the next one by the new deadlines; one that could not be
// cancelled has fired and will do so itself. On the worker, so next_tick_ is never read while it is written.
void Fleet::tick_sooner() {
  worker_->post([this] {
    if (!stopping_ && worker_->cancel(next_tick_)) tick();
  });
}

std::optional<FleetPose> Fleet::position() const {
  if (const auto* source = sdk::find<sdk::PoseSource>(ctx_)) {
    const sdk::PoseReading reading = source->read();
    if (!reading.available) return std::nullopt;
    return sdk::compose(settings_.origin, reading.pose);
  }
  const auto& caps = settings_.capabilities;
  if (std::find(caps.begin(), caps.end(), "nav") != caps.end()) return std::nullopt;
  return settings_.origin;
}

sdk::Json Fleet::status() const {
  if (!auctions_) return {{"r2r", false}};
  return {{"tasks_held", auctions_->tasks_held()}, {"auctions", auctions_->auctions()}};
}

void Fleet::shutdown() noexcept {
  if (stopping_.exchange(true) || !auctions_) return;
  auctions_->unsubscribe();      // no message reaches the auctions from here on
  auctions_->abandon_waiting();  // rcand's R2R service answered them already when it stopped; this is the backstop
}

}  // namespace rcand::plugins::fleet
