// The service directory (issue 14 item 4, rcand/sdk/services.hpp): one provider per id, found by id with no RTTI,
// withdrawn with its instance, hidden once the instance failed; and the instance context that plugins reach it by.
#include <doctest/doctest.h>

#include <rcand/sdk/interfaces/obstacle_source.hpp>
#include <rcand/sdk/interfaces/pose_source.hpp>
#include <rcand/sdk/interfaces/trip_estimator.hpp>
#include <rcand/sdk/testing/manual_clock.hpp>

#include <atomic>
#include <thread>
#include <vector>

#include "kernel/plugins/instance_context.hpp"
#include "kernel/plugins/service_directory.hpp"
#include "kernel/safety/estop.hpp"
#include "kernel/safety/kernel_motion_gate.hpp"

using namespace rcand;
using namespace rcand::kernel;
using nlohmann::json;

namespace {

struct StillPose final : sdk::PoseSource {
  sdk::PoseReading read() const noexcept override { return {true, {1.0, 2.0, 90.0}, false}; }
};

struct FixedTrips final : sdk::TripEstimator {
  std::optional<double> trip_seconds(const sdk::Pose2d&, double, double, double) const noexcept override { return 7.0; }
};

// One object behind two interfaces: each offer must hand out the right base, not the object's address.
struct Both final : sdk::PoseSource, sdk::TripEstimator {
  sdk::PoseReading read() const noexcept override { return {true, {3.0, 4.0, 0.0}, true}; }
  std::optional<double> trip_seconds(const sdk::Pose2d&, double, double, double) const noexcept override { return 2.5; }
};

struct Near final : sdk::ObstacleSource {
  sdk::ObstacleReading obstacles() const noexcept override { return {true, 10, 10, 10, 10, 0}; }
};

struct DirectoryRig {
  sdk::testing::ManualClock clock;
  ActuatorTable actuators;
  Estop estop{clock, actuators};
  KernelMotionGate gate{actuators, estop};
  sdk::ConfigView robot_config;
  KernelServices services{clock, estop, gate, robot_config, nullptr, "rcan://test/robot", {}};
};

}  // namespace

TEST_CASE("directory: offer, find by id, one provider per id, unknown ids are null") {
  ServiceDirectory directory;
  StillPose pose;
  FixedTrips trips;
  int nav = 0, other = 0;  // owners are identities only
  CHECK(sdk::find<sdk::PoseSource>(directory) == nullptr);
  CHECK(directory.service("rcand.nothing/1") == nullptr);

  CHECK(directory.offer_service(sdk::PoseSource::kServiceId, static_cast<const sdk::PoseSource*>(&pose), &nav, "nav", nullptr));
  CHECK(directory.offer_service(sdk::TripEstimator::kServiceId, static_cast<const sdk::TripEstimator*>(&trips), &nav, "nav",
                                nullptr));
  REQUIRE(sdk::find<sdk::PoseSource>(directory) == &pose);
  CHECK(sdk::find<sdk::PoseSource>(directory)->read().pose.heading_deg == 90.0);
  CHECK(*sdk::find<sdk::TripEstimator>(directory)->trip_seconds({}, 1, 1, 0.5) == 7.0);

  StillPose second;
  CHECK_FALSE(directory.offer_service(sdk::PoseSource::kServiceId, static_cast<const sdk::PoseSource*>(&second), &other, "other",
                                      nullptr));
  CHECK(sdk::find<sdk::PoseSource>(directory) == &pose);  // the first stays
  CHECK_FALSE(directory.offer_service("", &second, &other, "other", nullptr));
  CHECK_FALSE(directory.offer_service("rcand.pose_source/2", nullptr, &other, "other", nullptr));
  CHECK(directory.service("rcand.pose_source/2") == nullptr);  // another version is another id
}

TEST_CASE("directory: an owner's offers are withdrawn together; a failed owner's offers are not found") {
  ServiceDirectory directory;
  StillPose pose;
  FixedTrips trips;
  Near near;
  InstanceHealth nav_health, vision_health;
  int nav = 0, vision = 0;
  REQUIRE(directory.offer_service(sdk::PoseSource::kServiceId, &pose, &nav, "nav", &nav_health));
  REQUIRE(directory.offer_service(sdk::TripEstimator::kServiceId, &trips, &nav, "nav", &nav_health));
  REQUIRE(directory.offer_service(sdk::ObstacleSource::kServiceId, &near, &vision, "vision", &vision_health));

  vision_health.mark_failed("depth pipeline threw");
  CHECK(sdk::find<sdk::ObstacleSource>(directory) == nullptr);
  CHECK(sdk::find<sdk::PoseSource>(directory) != nullptr);

  directory.withdraw(&nav);
  CHECK(sdk::find<sdk::PoseSource>(directory) == nullptr);
  CHECK(sdk::find<sdk::TripEstimator>(directory) == nullptr);
  directory.withdraw(&nav);  // idempotent
  // Withdrawn, the id is free for another provider.
  StillPose next;
  CHECK(directory.offer_service(sdk::PoseSource::kServiceId, &next, &vision, "vision", nullptr));
  CHECK(sdk::find<sdk::PoseSource>(directory) == &next);
}

TEST_CASE("directory: finds from many threads while offers and withdrawals happen") {
  ServiceDirectory directory;
  StillPose pose;
  int owner = 0;
  std::atomic<bool> stop{false};
  std::atomic<long> seen{0};
  std::vector<std::thread> finders;
  for (int i = 0; i < 3; ++i)
    finders.emplace_back([&] {
      while (!stop.load())
        if (const auto* found = sdk::find<sdk::PoseSource>(directory)) seen += found->read().available ? 1 : 0;
    });
  for (int round = 0; round < 500; ++round) {
    REQUIRE(directory.offer_service(sdk::PoseSource::kServiceId, &pose, &owner, "nav", nullptr));
    directory.withdraw(&owner);
  }
  stop = true;
  for (auto& thread : finders) thread.join();
  CHECK(sdk::find<sdk::PoseSource>(directory) == nullptr);
}

TEST_CASE("instance contexts: typed offer and find across instances; the context's end withdraws its offers") {
  DirectoryRig rig;
  InstanceHealth nav_health, fleet_health;
  Both both;
  {
    InstanceContext nav{"org.rcand.nav", "nav", rig.services, json::object(), nav_health};
    InstanceContext fleet{"org.rcand.fleet", "fleet", rig.services, json::object(), fleet_health};
    CHECK(sdk::find<sdk::TripEstimator>(fleet) == nullptr);  // not offered yet: null, never an error
    REQUIRE(sdk::offer<sdk::PoseSource>(nav, both));
    REQUIRE(sdk::offer<sdk::TripEstimator>(nav, both));
    // Each interface arrives as its own base of the same object.
    REQUIRE(sdk::find<sdk::TripEstimator>(fleet) == static_cast<const sdk::TripEstimator*>(&both));
    CHECK(*sdk::find<sdk::TripEstimator>(fleet)->trip_seconds({}, 0, 0, 0.5) == 2.5);
    CHECK(sdk::find<sdk::PoseSource>(fleet)->read().busy);
    CHECK(sdk::find<sdk::PoseSource>(rig.services.directory) == static_cast<const sdk::PoseSource*>(&both));
    CHECK_FALSE(sdk::offer<sdk::PoseSource>(fleet, both));  // nav has it

    nav.withdraw_offers();  // what the plugin runtime does before nav's shutdown()
    CHECK(sdk::find<sdk::PoseSource>(fleet) == nullptr);
    REQUIRE(sdk::offer<sdk::PoseSource>(nav, both));
  }
  CHECK(sdk::find<sdk::PoseSource>(rig.services.directory) == nullptr);  // gone with its context
}

TEST_CASE("obstacles(), the deprecated shim, answers the ObstacleSource service") {
  DirectoryRig rig;
  InstanceHealth vision_health, nav_health;
  InstanceContext vision{"org.rcand.vision", "vision", rig.services, json::object(), vision_health};
  InstanceContext nav{"org.rcand.nav", "nav", rig.services, json::object(), nav_health};
  CHECK(nav.obstacles() == nullptr);
  Near near;
  REQUIRE(sdk::offer<sdk::ObstacleSource>(vision, near));
  CHECK(nav.obstacles() == &near);
  CHECK(sdk::find<sdk::ObstacleSource>(nav) == &near);
  vision_health.mark_failed("camera gone");
  CHECK(nav.obstacles() == nullptr);
}
