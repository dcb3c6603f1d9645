// chat's brain-call metrics on the fake host, seen through the SDK's RecordingMetrics: one call answered, a failing
// brain followed by the grammar brain's fallback, each with its latency; and how an outcome is told.
#include <rcand/sdk/testing/recording_metrics.hpp>

#include "brain_metrics.hpp"
#include "chat_fixture.hpp"

using namespace chat_test;
using rcand::plugins::chat::brain_outcome;
using rcand::plugins::chat::BrainOutcome;
using rcand::sdk::testing::RecordingMetrics;

TEST_CASE("brain metrics: an answered call, then a failed one and the grammar brain's fallback") {
  RecordingMetrics metrics;  // outlives the host, which holds a pointer to it
  Fixture f(rover_config(json::object(), {{"provider", "spy"}}));
  REQUIRE(sdk::offer<sdk::Metrics>(f.host, metrics));

  f.spy.answer = [](const sdk::BrainRequest&, sdk::CancelToken) { return spy_says(waypoint(1, 0)); };
  REQUIRE(f.say("go forward 1 metre")->status() == 200);
  CHECK(metrics.value("rcand_chat_brain_calls_total", {"spy", "spy-1", "answered"}) == 1);
  CHECK(metrics.observations("rcand_chat_brain_call_duration_seconds", {"spy", "spy-1"}).size() == 1);

  f.spy.answer = [](const sdk::BrainRequest&, sdk::CancelToken) {
    sdk::Proposal p;
    p.error = "model unavailable";
    return p;
  };
  REQUIRE(f.say("close the gripper")->status() == 200);
  CHECK(metrics.value("rcand_chat_brain_calls_total", {"spy", "unknown", "error"}) == 1);
  CHECK(metrics.value("rcand_chat_brain_calls_total", {"grammar", "grammar-en-1", "fallback"}) == 1);
  CHECK(metrics.refusals().empty());
}

TEST_CASE("brain metrics: the outcome of one call") {
  sdk::Proposal answered;
  sdk::Proposal failed;
  failed.error = "no answer before chat's deadline (10000 ms)";
  CHECK(brain_outcome(answered, false, false) == BrainOutcome::Answered);
  CHECK(brain_outcome(answered, false, true) == BrainOutcome::Fallback);
  CHECK(brain_outcome(failed, false, false) == BrainOutcome::Error);
  CHECK(brain_outcome(failed, true, false) == BrainOutcome::Timeout);  // failed with its deadline passed
}
