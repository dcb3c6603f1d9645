// The host's side of the channel (host_session.hpp, host_context.hpp), driven from this test as rcand would: the
// capability is a class of this test handed in by a loader, so every message can be checked on its own.
#include "libs/isolation/host_session.hpp"

#include <doctest/doctest.h>

#include <atomic>
#include <future>
#include <stdexcept>
#include <thread>

#include "libs/isolation/wire.hpp"
#include "rcand/sdk/plugin.hpp"

using namespace rcand;
using isolation::Channel;
using nlohmann::json;

namespace {

struct Seen {
  std::atomic<int> estops{0}, shutdowns{0};
  std::atomic<bool> offered{true};
};

class Probe final : public sdk::Capability {
 public:
  Probe(sdk::PluginContext& context, Seen& seen) : context_(context), seen_(seen) {}
  void start() override {
    if (context_.config().get_or<bool>("read_drive_on_start", false))  // waits for rcand's answer inside start()
      context_.motion().inspect("drive0", [](const sdk::ActuatorDriver& drive) { (void)drive.status(); });
    context_.log().info("probe starting with speed ", context_.config().get_or<double>("speed", 0.0));
    context_.publish_status({{"phase", "started"}});
    seen_.offered = context_.offer_service("com.acme.thing/1", this);
  }
  std::vector<sdk::Route> routes() override {
    sdk::Route echo{
        "POST", "/echo", sdk::Scope::Control,
        false,  "",      [](const sdk::Request& r) {
                      return sdk::Response::ok({{"body", r.body}, {"principal", r.principal}}); }};
    sdk::Route latched{
        "GET", "/latched", sdk::Scope::Status,
        false, "",         [this](const sdk::Request&) { return sdk::Response::ok({{"latched", context_.estop().latched()}}); }};
    sdk::Route drive{"POST", "/drive", sdk::Scope::Control, true, "", [this](const sdk::Request&) {
                       const auto status = context_.motion().actuate_as<sdk::DifferentialDrive>(
                           "drive0", [](sdk::DifferentialDrive& d) { d.set_wheel_speeds(0.5, -0.5); });
                       return sdk::gate_refusal(status, "drive0");
                     }};
    sdk::Route grip{"POST", "/grip", sdk::Scope::Control, true, "", [this](const sdk::Request&) {
                      return sdk::gate_refusal(context_.motion().actuate("gripper0", [](sdk::ActuatorDriver&) {}), "gripper0");
                    }};
    sdk::Route fails{"POST", "/fails", sdk::Scope::Control,
                     false,  "",       [](const sdk::Request&) -> sdk::Response { throw std::runtime_error("out of paper"); }};
    return {echo, latched, drive, grip, fails};
  }
  sdk::Json status() const override { return {{"phase", "running"}}; }
  void on_estop() noexcept override { context_.publish_status({{"estops", ++seen_.estops}}); }
  void shutdown() noexcept override { ++seen_.shutdowns; }

 private:
  sdk::PluginContext& context_;
  Seen& seen_;
};

json start_message(json settings = {{"speed", 0.5}}) {
  return {{"t", "start"},
          {"plugin_paths", json::array()},
          {"plugin", "com.acme.probe"},
          {"capability", "com.acme.probe"},
          {"settings", std::move(settings)},
          {"robot_config", {{"metadata", {{"robot_name", "r"}}}}},
          {"actuators", json::array({json::array({"drive0", "differential_drive"}), json::array({"gripper0", "gripper"})})},
          {"latched", false}};
}

// rcand's end, and the host's session on a thread of its own.
struct Session {
  Seen seen;
  std::pair<int, int> fds = Channel::socket_pair();
  Channel rcand_end{fds.first};
  Channel host_end{fds.second};
  std::future<int> exit_status;

  explicit Session(isolation::CapabilityLoader loader = {}, json start = start_message()) {
    if (!loader)
      loader = [this](const json&) {
        return isolation::LoadedCapability{[this](sdk::PluginContext& c) { return std::make_unique<Probe>(c, seen); }, 3,
                                           nullptr};
      };
    exit_status = std::async(std::launch::async, [this, loader] { return isolation::run_host(host_end, nullptr, loader); });
    REQUIRE(rcand_end.send(start));
  }
  ~Session() {
    rcand_end.send({{"t", "shutdown"}});
    if (exit_status.valid()) exit_status.wait();
  }
  // The next message of type `type`; the log lines and publishes before it are kept in `others`.
  json next(const std::string& type) {
    for (;;) {
      auto message = rcand_end.receive();
      REQUIRE(message);
      if (message->at("t") == type) return *message;
      others.push_back(*message);
    }
  }
  json request(std::size_t route, json body = nullptr) {
    sdk::Request r;
    r.method = "POST";
    r.principal = "ops";
    r.body = std::move(body);
    REQUIRE(rcand_end.send({{"t", "request"}, {"id", ++id}, {"route", route}, {"req", isolation::encode_request(r)}}));
    auto answer = next("response");
    CHECK(answer.at("id") == id);
    return answer;
  }
  std::vector<json> others;
  std::uint64_t id = 0;
};

}  // namespace

TEST_CASE("host session: started with the capability's routes; its log lines and status reach rcand") {
  Session session;
  const auto started = session.next("started");
  REQUIRE(started.at("routes").at("routes").size() == 5);
  CHECK(isolation::decode_route(started["routes"]["routes"][2]).motion);
  bool logged = false, published = false;
  for (const auto& m : session.others) {
    logged |= m["t"] == "log" && m["text"] == "probe starting with speed 0.5";
    published |= m["t"] == "publish" && m["status"] == json{{"phase", "started"}};
  }
  CHECK(logged);
  CHECK(published);
  CHECK(session.seen.offered.load());  // offered within its own process (chat's brains): found by itself alone
}

TEST_CASE("host session: requests answered in order; what a handler throws goes to rcand, and the host goes on") {
  Session session;
  session.next("started");
  const auto echo = session.request(0, {{"x", 1}});
  CHECK(echo["status"] == 200);
  CHECK(echo["body"] == json{{"body", {{"x", 1}}}, {"principal", "ops"}});
  const auto failed = session.request(4);
  CHECK(failed["threw"] == "out of paper");  // rcand answers 500, logs and counts it, as for a handler in process
  CHECK_FALSE(failed.contains("body"));
  CHECK(session.request(0)["status"] == 200);
}

TEST_CASE("host session: the heartbeat and the e-stop: pong, the latch mirrored, on_estop() called") {
  Session session;
  session.next("started");
  REQUIRE(session.rcand_end.send({{"t", "ping"}, {"latched", false}}));
  session.next("pong");
  CHECK(session.request(1)["body"]["latched"] == false);
  REQUIRE(session.rcand_end.send({{"t", "estop"}}));
  CHECK(session.next("publish")["status"] == json{{"estops", 1}});  // its on_estop() ran, on a thread of its own
  CHECK(session.request(1)["body"]["latched"] == true);
  REQUIRE(session.rcand_end.send({{"t", "ping"}, {"latched", false}}));  // cleared in rcand: the next ping says so
  session.next("pong");
  CHECK(session.request(1)["body"]["latched"] == false);
  REQUIRE(session.rcand_end.send({{"t", "status?"}, {"id", 7}}));
  const auto status = session.next("status");
  CHECK(status["id"] == 7);
  CHECK(status["status"] == json{{"phase", "running"}});
}

TEST_CASE("host session: a motion is a call to rcand's gate, and rcand's answer is the plugin's") {
  Session session;
  session.next("started");
  for (const auto gate : {sdk::GateStatus::Ok, sdk::GateStatus::EstopActive}) {
    CAPTURE(static_cast<int>(gate));
    sdk::Request r;
    REQUIRE(session.rcand_end.send({{"t", "request"}, {"id", 50}, {"route", 2}, {"req", isolation::encode_request(r)}}));
    const auto call = session.next("call");
    CHECK(call["op"] == "actuate");
    CHECK(call["actuator"] == "drive0");
    CHECK(call["method"] == "set_wheel_speeds");
    CHECK(call["args"] == json::array({0.5, -0.5}));
    REQUIRE(session.rcand_end.send({{"t", "reply"}, {"id", call["id"]}, {"gate", static_cast<int>(gate)}, {"result", nullptr}}));
    const auto answer = session.next("response");
    CHECK(answer["status"] == (gate == sdk::GateStatus::Ok ? 200 : 423));
  }
  // An interface not carried yet is refused in the host, named in the log, and nothing reaches rcand.
  const auto grip = session.request(3);
  CHECK(grip["status"] == 503);
  bool named = false;
  for (const auto& m : session.others)
    named |=
        m["t"] == "log" && m["text"].get<std::string>().find("implements gripper, which is not carried") != std::string::npos;
  CHECK(named);
}

TEST_CASE("host session: a capability that asks rcand something in its start() gets the answer, then starts") {
  Session session({}, start_message({{"read_drive_on_start", true}}));
  const auto call = session.next("call");
  CHECK(call["op"] == "inspect");
  CHECK(call["method"] == "status");
  REQUIRE(session.rcand_end.send({{"t", "reply"}, {"id", call["id"]}, {"gate", 0}, {"result", {{"left", 0}}}}));
  CHECK(session.next("started")["routes"]["routes"].size() == 5);
}

TEST_CASE("host session: a capability that cannot be loaded or started says why, and the host ends with 3") {
  Session session([](const json&) -> isolation::LoadedCapability {
    throw std::runtime_error("plugin com.acme.probe is incompatible: built for ABI 2");
  });
  const auto failed = session.next("start_failed");
  CHECK(failed["reason"] == "plugin com.acme.probe is incompatible: built for ABI 2");
  CHECK(session.exit_status.get() == 3);
}

TEST_CASE("host session: shutdown() reaches the capability and the host ends with 0") {
  Session session;
  session.next("started");
  REQUIRE(session.rcand_end.send({{"t", "shutdown"}}));
  CHECK(session.exit_status.get() == 0);
  CHECK(session.seen.shutdowns.load() == 1);
}
