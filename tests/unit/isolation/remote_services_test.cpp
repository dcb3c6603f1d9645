// The services carried out of an isolated capability's process: rcand's metrics (checked by the SDK's rules in the host,
// recorded in rcand) and the plugin's obstacle source (polled in the host, answered in rcand from the newest reading).
#include <doctest/doctest.h>

#include <array>
#include <future>
#include <thread>

#include "eventually.hpp"
#include "libs/isolation/remote_dispatcher.hpp"
#include "libs/isolation/remote_metrics.hpp"
#include "libs/isolation/remote_obstacles.hpp"

using namespace rcand::isolation;
using namespace std::chrono_literals;
using nlohmann::json;

namespace {

struct ServicePair {
  std::pair<int, int> fds = Channel::socket_pair();
  Channel rcand_end{fds.first}, host_end{fds.second};
};

// What rcand's telemetry would have been asked to record.
struct Recorded final : rcand::sdk::Metrics {
  mutable std::vector<std::string> calls;
  bool record(const rcand::sdk::MetricFamily& family, std::span<const std::string_view> labels, rcand::sdk::MetricOp op,
              double value) const noexcept override {
    std::string call = std::string(family.name) + " " + std::string(family.help) + " op" + std::to_string(static_cast<int>(op));
    for (std::size_t i = 0; i < labels.size(); ++i) call += " " + std::string(family.labels[i]) + "=" + std::string(labels[i]);
    calls.push_back(call + " " + std::to_string(value));
    return true;
  }
};

constexpr std::array<std::string_view, 1> kStage{"stage"};
constexpr rcand::sdk::MetricFamily kFps{"acme_frames_per_second", rcand::sdk::MetricType::Gauge, "frames a second", kStage};
constexpr rcand::sdk::MetricFamily kBadCounter{"acme_frames", rcand::sdk::MetricType::Counter, "no _total", {}};

struct Source final : rcand::sdk::ObstacleSource {
  std::atomic<std::int64_t> at{0};
  rcand::sdk::ObstacleReading obstacles() const noexcept override { return {at.load() != 0, 100, 40, 120, 40, at.load()}; }
};

}  // namespace

TEST_CASE(
    "metrics from the host: a valid sample is recorded in rcand with its labels; one the rules refuse is false "
    "in the host and never sent") {
  ServicePair pair;
  const RemoteMetrics metrics(pair.host_end);
  CHECK(metrics.set(kFps, {"encoded"}, 29.5));
  CHECK_FALSE(metrics.add(kBadCounter));
  CHECK_FALSE(metrics.set(kFps, {"encoded", "extra"}, 1));
  Recorded recorded;
  record_remote_metric(&recorded, *pair.rcand_end.receive());
  REQUIRE(recorded.calls.size() == 1);
  CHECK(recorded.calls[0] == "acme_frames_per_second frames a second op2 stage=encoded 29.500000");
  // Nothing else was sent: the next message is the one sent now.
  CHECK(metrics.declare(kFps));
  CHECK(pair.rcand_end.receive()->at("op") == static_cast<int>(rcand::sdk::MetricOp::Declare));
  record_remote_metric(nullptr, {{"t", "metric"}});  // rcand without metrics: nothing to do, nothing read
}

TEST_CASE(
    "obstacles from the host: each new reading reaches rcand, which answers from the newest without waiting, and "
    "says unavailable once the host is gone") {
  ServicePair pair;
  Source source;
  RemoteObstacles remote;
  CHECK_FALSE(remote.obstacles().available);
  std::thread reader([&] {
    while (const auto message = pair.rcand_end.receive()) remote.update(*message);
  });
  {
    ObstaclePoller poller(pair.host_end, source);
    source.at = 1000;
    REQUIRE(rcand::test::eventually([&] { return remote.obstacles().timestamp_ms == 1000; }, 2s));
    CHECK(remote.obstacles().available);
    CHECK(remote.obstacles().nearest_cm == 40);
    source.at = 2000;
    REQUIRE(rcand::test::eventually([&] { return remote.obstacles().timestamp_ms == 2000; }, 2s));
  }
  remote.lost();
  CHECK_FALSE(remote.obstacles().available);
  pair.rcand_end.shutdown();
  reader.join();
}

namespace {

struct Credential final : rcand::sdk::Credential {};

// rcand's dispatcher as the host's dispatch reaches it: what it was asked, and its answer.
struct FakeDispatcher final : rcand::sdk::RequestDispatcher {
  mutable rcand::sdk::Request seen;
  void dispatch(rcand::sdk::Request request, rcand::sdk::Json,
                std::function<void(rcand::sdk::Response)> done) const noexcept override {
    seen = std::move(request);
    done(rcand::sdk::Response::ok({{"moved", true}}));
  }
};

}  // namespace

TEST_CASE(
    "dispatch from the host: the caller's credential stays in rcand behind a handle; the answer reaches done; a "
    "handle let go, forgotten, or a closed channel runs nothing") {
  ServicePair pair;
  CredentialTable credentials;
  const auto caller = std::make_shared<const Credential>();
  const json handle = credentials.keep(caller);
  CHECK(credentials.keep(nullptr).is_null());
  {
    RemoteDispatcher dispatcher(pair.host_end);
    rcand::sdk::Request request;
    request.method = "POST", request.path = "/api/nav/waypoint", request.principal = "someone-else";
    request.credential = dispatcher.credential(handle);  // what the plugin got with the request it acts for
    std::promise<rcand::sdk::Response> answered;
    dispatcher.dispatch(request, {{"ai", {{"provider", "grammar"}}}}, [&](rcand::sdk::Response r) { answered.set_value(r); });
    const auto message = pair.rcand_end.receive();
    REQUIRE(message);
    CHECK(message->at("cred") == handle);  // a number, never the credential
    FakeDispatcher rcand_dispatcher;
    auto rcand_end = std::shared_ptr<Channel>(&pair.rcand_end, [](Channel*) {});
    dispatch_for_host(&rcand_dispatcher, credentials, *message, rcand_end);
    CHECK(rcand_dispatcher.seen.credential == caller);  // rcand's own object, found by the handle
    CHECK(rcand_dispatcher.seen.path == "/api/nav/waypoint");
    dispatcher.answered(*pair.host_end.receive());
    auto future = answered.get_future();
    REQUIRE(future.wait_for(2s) == std::future_status::ready);
    CHECK(future.get().body["moved"] == true);

    // A handle rcand forgot (or never gave) finds no credential: rcand's dispatcher refuses such a request 401.
    credentials.drop(handle);
    dispatch_for_host(&rcand_dispatcher, credentials, *message, rcand_end);
    CHECK(rcand_dispatcher.seen.credential == nullptr);
    pair.host_end.receive();  // its answer

    std::promise<rcand::sdk::Response> closed;
    dispatcher.close();
    dispatcher.dispatch(request, nullptr, [&](rcand::sdk::Response r) { closed.set_value(r); });
    CHECK(closed.get_future().get().status == 503);
    request.credential.reset();
  }  // the plugin let go of the credential: rcand is told to forget it
  bool told = false;
  while (const auto message = pair.rcand_end.receive()) {
    if (message->at("t") == "cred_drop") {
      told = message->at("cred") == handle;
      break;
    }
  }
  CHECK(told);
}

TEST_CASE("credential table: at most kMaxCredentials kept, the oldest forgotten first") {
  CredentialTable credentials;
  const auto first = credentials.keep(std::make_shared<const Credential>());
  for (std::size_t i = 0; i < CredentialTable::kMaxCredentials; ++i) credentials.keep(std::make_shared<const Credential>());
  CHECK(credentials.find(first) == nullptr);
  CHECK(credentials.find(json(first.get<std::uint64_t>() + 1)) != nullptr);
  CHECK(credentials.find("not a handle") == nullptr);
}
