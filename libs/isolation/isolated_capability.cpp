#include "libs/isolation/isolated_capability.hpp"

#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <utility>

#include "libs/base/logging.hpp"
#include "libs/isolation/actuator_calls.hpp"
#include "libs/isolation/host_process.hpp"
#include "libs/isolation/remote_metrics.hpp"
#include "libs/isolation/remote_pose.hpp"
#include "libs/isolation/wire.hpp"

namespace rcand::isolation {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

namespace {

std::string ms_text(std::chrono::milliseconds ms) { return std::to_string(ms.count()) + " ms"; }

}  // namespace

IsolatedCapability::IsolatedCapability(sdk::PluginContext& context, HostSpec spec, HostEvents events)
    : context_(context),
      spec_(std::move(spec)),
      events_(std::move(events)),
      calls_("cap." + std::string(context.instance_id()).substr(0, 6) + ".gate", [](const std::string&) {}) {}

IsolatedCapability::~IsolatedCapability() { shutdown(); }

void IsolatedCapability::start() {
  // The supervisor starts every host, this first one too: a child's PR_SET_PDEATHSIG follows the thread that
  // started it, and only the supervisor lives as long as the capability.
  supervisor_ = std::thread([this] { supervise(); });
  std::unique_lock lock(mutex_);
  changed_.wait(lock, [&] { return up_ || failed_; });
  if (!up_) throw std::runtime_error("isolated: " + down_reason_);
}

// Under mutex_. A new host process and its reader; the start message names what it runs.
void IsolatedCapability::spawn() {
  auto [mine, theirs] = Channel::socket_pair();
  auto channel = std::make_shared<Channel>(mine);
  pid_t pid = 0;
  std::shared_ptr<FrameRing> ring;
  try {
    ring = FrameRing::create();
    pid = spawn_host(spec_.binary, theirs, ring->fd());
  } catch (...) {
    ::close(theirs);
    throw;
  }
  ::close(theirs);
  json actuators = json::array();
  for (const auto& info : context_.motion().actuators()) actuators.push_back({info.id, info.interface});
  channel->send(with_pose({{"t", "start"},
                           {"plugin_paths", spec_.plugin_paths},
                           {"plugin", spec_.plugin_id},
                           {"capability", std::string(context_.instance_id())},
                           {"settings", context_.config().raw()},
                           {"robot_config", context_.robot_config().raw()},
                           {"actuators", actuators},
                           {"latched", context_.estop().latched()},
                           {"sandbox",
                            {{"network", spec_.isolation.network},
                             {"video", spec_.isolation.video},
                             {"serial", spec_.isolation.serial},
                             {"hidden", spec_.hidden}}}}));
  start_error_.clear();
  kill_reason_.clear();
  host_ = Host{pid, channel, ring, {}, false, Clock::now(), Clock::now()};
  host_.reader = std::thread([this, channel, ring] { read(channel, ring); });
}

void IsolatedCapability::read(std::shared_ptr<Channel> channel, std::shared_ptr<FrameRing> ring) {
  while (auto message = channel->receive()) {
    try {
      handle(*message, channel, ring.get());
    } catch (const std::exception& e) {
      logger("isolation")->error("capability {}: a message of its process does not decode: {}", context_.instance_id(), e.what());
    }
  }
  std::lock_guard lock(mutex_);
  if (host_.channel == channel) host_.gone = true;
  changed_.notify_all();
}

void IsolatedCapability::handle(const json& message, const std::shared_ptr<Channel>& channel, FrameRing* ring) {
  const std::string type = message.at("t").get<std::string>();
  if (type.starts_with("s_")) {
    // A stream of a buried host was ended: its ids reach nothing.
    if (const auto answer = streams_.deliver(message, ring)) channel->send(*answer, nullptr, /*wait=*/false);
  } else if (type == "obstacles") {
    obstacles_.update(message);
  } else if (type == "dispatch") {
    dispatch_for_host(sdk::find<sdk::RequestDispatcher>(context_), credentials_, message, channel);
  } else if (type == "cred_drop") {
    credentials_.drop(message.at("cred"));
  } else if (type == "metric") {
    record_remote_metric(sdk::find<sdk::Metrics>(context_), message);
  } else if (type == "call") {
    // A host has one call in flight per thread of its plugin; one that floods rcand is refused, not queued.
    if (calls_in_flight_.fetch_add(1) >= kMaxCallsInFlight) {
      calls_in_flight_.fetch_sub(1);
      channel->send({{"t", "reply"},
                     {"id", message.value("id", json())},
                     {"gate", static_cast<int>(sdk::GateStatus::Ok)},
                     {"error", "more than " + std::to_string(kMaxCallsInFlight) + " calls in flight"}},
                    nullptr, /*wait=*/false);
      return;
    }
    calls_.post([this, message, channel] {
      answer_call(message, channel);
      calls_in_flight_.fetch_sub(1);
    });
  } else if (type == "publish") {
    json status;
    {
      std::lock_guard lock(mutex_);
      status = with_process(message.at("status"));
    }
    context_.publish_status(status);
  } else if (type == "log") {
    const int level = std::clamp(message.at("level").get<int>(), 0, static_cast<int>(sdk::LogLevel::Error));
    context_.log().log(static_cast<sdk::LogLevel>(level), message.at("text").get<std::string>());
  } else {
    std::lock_guard lock(mutex_);
    if (host_.channel != channel) return;  // a message of a host already buried
    if (type == "pong") {
      host_.last_pong = Clock::now();
    } else if (type == "response") {
      if (auto it = requests_.find(message.at("id").get<std::uint64_t>()); it != requests_.end()) {
        Answer answer;
        if (message.contains("threw")) answer.threw = message["threw"].get<std::string>();
        else answer.response = sdk::Response{message.at("status").get<int>(), message.at("body")};
        it->second = std::move(answer);
      }
    } else if (type == "status") {
      if (auto it = statuses_.find(message.at("id").get<std::uint64_t>()); it != statuses_.end())
        it->second = message.at("status");
    } else if (type == "started") {
      for (const auto& route : message.at("routes").at("routes")) decode_route(route);  // each one decodes, or none serves
      for (const auto& route : message.at("routes").at("streams")) decode_stream_route(route);
      if (!route_specs_) route_specs_ = message.at("routes");
      if (*route_specs_ == message.at("routes")) {
        up_ = true;
        down_reason_.clear();
      } else {
        start_error_ = "its routes after a restart differ from those it started with";
        kill_host(start_error_);
      }
    } else if (type == "sandbox") {
      sandbox_ = message.at("sandbox").is_object() ? message["sandbox"] : json::object();
      if (sandbox_.value("devices", "") != "restricted")
        logger("isolation")
            ->warn("capability {}: its process may open every file and device rcand's user may: {}", context_.instance_id(),
                   sandbox_.value("reason", "its host did not restrict them"));
    } else if (type == "start_failed") {
      start_error_ = message.at("reason").get<std::string>();
    }
    changed_.notify_all();
  }
}

// On the calls worker: one call of the host on an actuator (or its e-stop request), through this process's gate, and
// its answer. The host is not trusted: a call that does not decode is answered with an error and reaches nothing.
void IsolatedCapability::answer_call(const json& call, const std::shared_ptr<Channel>& channel) {
  json reply{{"t", "reply"}, {"id", call.value("id", json())}, {"result", nullptr}};
  sdk::GateStatus status = sdk::GateStatus::Ok;
  try {
    const std::string op = call.at("op").get<std::string>(), actuator = call.at("actuator").get<std::string>(),
                      method = call.at("method").get<std::string>();
    {
      std::lock_guard lock(mutex_);
      if (host_.channel != channel) return;  // its process ended: nothing it asked for moves anything now
    }
    if (op == "actuate") {
      const ActuatorCommand command = command_for(method, call.at("args"));  // a bad call never reaches the gate
      {
        std::lock_guard lock(mutex_);
        moved_.insert(actuator);
      }
      bool wrong_interface = false;
      status = context_.motion().actuate(actuator, [&](sdk::ActuatorDriver& driver) { wrong_interface = !command(driver); });
      if (wrong_interface) status = sdk::GateStatus::WrongInterface;
    } else if (op == "inspect") {
      const ActuatorReading reading = reading_for(method);
      bool wrong_interface = false;
      status = context_.motion().inspect(actuator, [&](const sdk::ActuatorDriver& driver) {
        auto result = reading(driver);
        wrong_interface = !result;
        if (result) reply["result"] = std::move(*result);
      });
      if (wrong_interface) status = sdk::GateStatus::WrongInterface;
    } else if (op == "halt") {
      context_.motion().halt(actuator);
    } else if (op == "offer" && method == sdk::ObstacleSource::kServiceId) {  // a later host offers it again: still ours
      if (!obstacles_offered_) obstacles_offered_ = sdk::offer<sdk::ObstacleSource>(context_, obstacles_);
      reply["result"] = obstacles_offered_;
    } else if (op == "estop") {
      context_.estop().request_estop(call.at("args").get<std::string>());
    } else {
      reply["error"] = "unknown call '" + op + "'";
    }
  } catch (const std::exception& e) {
    reply["error"] = e.what();
  }
  reply["gate"] = static_cast<int>(status);
  channel->send(reply);
}

std::vector<sdk::Route> IsolatedCapability::routes() {
  std::lock_guard lock(mutex_);
  std::vector<sdk::Route> routes;
  for (std::size_t i = 0; route_specs_ && i < route_specs_->at("routes").size(); ++i) {
    sdk::Route route = decode_route(route_specs_->at("routes").at(i));
    route.handler = [this, i](const sdk::Request& request) { return forward(i, request); };
    routes.push_back(std::move(route));
  }
  return routes;
}

std::vector<sdk::StreamRoute> IsolatedCapability::stream_routes() {
  std::lock_guard lock(mutex_);
  std::vector<sdk::StreamRoute> routes;
  for (std::size_t i = 0; route_specs_ && i < route_specs_->at("streams").size(); ++i) {
    sdk::StreamRoute route = decode_stream_route(route_specs_->at("streams").at(i));
    route.handler = [this, i](const sdk::Request& request, std::shared_ptr<sdk::StreamWriter> writer) {
      open_stream(i, request, std::move(writer));
    };
    routes.push_back(std::move(route));
  }
  return routes;
}

// The client's writer kept here under an id, the host's handler given that id; the handler's return awaited as in
// process (a throw is rethrown: rcand answers 500 and counts it).
void IsolatedCapability::open_stream(std::size_t route, const sdk::Request& request, std::shared_ptr<sdk::StreamWriter> writer) {
  const std::uint64_t id = streams_.open(writer);
  sdk::Response response = forward(route, request, id);
  if (response.status != 0) writer->respond(response);  // 503: the host is down, or did not take it in time
}

sdk::Response IsolatedCapability::forward(std::size_t route, const sdk::Request& request, std::optional<std::uint64_t> stream) {
  std::unique_lock lock(mutex_);
  if (!up_) return unavailable();
  const std::uint64_t id = ++next_id_, generation = generation_;
  requests_[id];
  const auto channel = host_.channel;
  lock.unlock();
  std::string error;
  json message = with_pose({{"t", stream ? "stream" : "request"},
                            {"id", id},
                            {"route", route},
                            {"req", encode_request(request)},
                            {"cred", credentials_.keep(request.credential)},
                            {"latched", context_.estop().latched()}});  // a clear since the last heartbeat, too
  if (stream) message["v"] = *stream;
  const bool sent = channel->send(message, &error);
  lock.lock();
  const bool answered = sent && changed_.wait_for(lock, spec_.request_timeout, [&] {
    return requests_[id].has_value() || generation_ != generation || stopping_;
  });
  auto answer = std::move(requests_[id]);
  requests_.erase(id);
  if (answer && answer->threw) throw std::runtime_error(*answer->threw);  // rcand answers it as in process
  if (answer) return std::move(answer->response);
  if (!sent) return sdk::Response::error(503, "UNAVAILABLE", "the request could not reach the capability's process: " + error);
  if (!answered) {
    const std::string why = "did not answer " + request.method + " " + request.path + " within " + ms_text(spec_.request_timeout);
    if (generation_ == generation) kill_host(why);
    return sdk::Response::error(503, "UNAVAILABLE",
                                "capability '" + std::string(context_.instance_id()) + "' " + why + "; its process is restarted",
                                {{"reason", why}});
  }
  return unavailable();
}

sdk::Response IsolatedCapability::unavailable() const {
  const std::string name(context_.instance_id());
  const std::string reason = down_reason_.empty() ? "its process is starting" : down_reason_;
  return sdk::Response::error(
      503, "UNAVAILABLE",
      failed_ ? "capability '" + name + "' failed: " + reason : "capability '" + name + "' is restarting: " + reason,
      {{"reason", reason}});
}

json IsolatedCapability::down_status() const { return with_process({{"fault", unavailable().body.value("error", "")}}); }

json IsolatedCapability::with_process(json status) const {
  if (status.is_object())
    status["process"] = {{"isolation", "process"}, {"pid", host_.pid}, {"restarts", restarts_}, {"sandbox", sandbox_}};
  return status;
}

sdk::Json IsolatedCapability::status() const {
  std::unique_lock lock(mutex_);
  if (!up_) return down_status();
  const std::uint64_t id = ++next_id_, generation = generation_;
  statuses_[id];
  const auto channel = host_.channel;
  lock.unlock();
  const bool sent = channel->send({{"t", "status?"}, {"id", id}});
  lock.lock();
  const bool answered =
      sent && changed_.wait_for(lock, kStatusWait, [&] { return statuses_[id].has_value() || generation_ != generation; });
  auto status = std::move(statuses_[id]);
  statuses_.erase(id);
  if (status) return with_process(std::move(*status));
  if (!answered) return with_process({{"fault", "its status() did not answer within " + ms_text(kStatusWait)}});
  return down_status();
}

void IsolatedCapability::on_estop() noexcept {
  std::shared_ptr<Channel> channel;
  {
    std::lock_guard lock(mutex_);
    channel = host_.channel;
  }
  if (channel) channel->send({{"t", "estop"}}, nullptr, /*wait=*/false);  // never waits behind a host that stopped reading
}

void IsolatedCapability::supervise() {
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    changed_.wait_for(lock, kHeartbeat, [&] { return stopping_ || host_.gone; });
    if (stopping_) break;
    if (host_.pid != 0 && host_.gone) bury(lock);
    else if (host_.pid != 0) check_alive();
    else if (!failed_ && Clock::now() >= restart_at_) {
      try {
        if (route_specs_) ++restarts_;  // the first host is no restart
        spawn();
      } catch (const std::exception& e) {
        down_reason_ = std::string("cannot start its process: ") + e.what();
        failed_ = true;
        changed_.notify_all();
        lock.unlock();
        if (events_.fail) events_.fail(down_reason_);
        lock.lock();
      }
    }
  }
  end_host(lock);
}

// Under mutex_: the heartbeat, the start deadline and the memory limit of the running host.
void IsolatedCapability::check_alive() {
  const auto now = Clock::now();
  if (!up_) {
    if (now - host_.started > spec_.start_timeout)
      kill_host("did not start its capability within " + ms_text(spec_.start_timeout));
    return;
  }
  if (now - host_.last_pong > kHeartbeatLimit)
    return kill_host("stopped answering its heartbeat for " + ms_text(kHeartbeatLimit));
  if (const auto resident = resident_bytes(host_.pid); resident && *resident > spec_.isolation.memory_mb << 20)
    return kill_host("used " + std::to_string(*resident >> 20) + " MB, over its limit of " +
                     std::to_string(spec_.isolation.memory_mb) + " MB (isolation_memory_mb)");
  host_.channel->send(with_pose({{"t", "ping"}, {"latched", context_.estop().latched()}}), nullptr, /*wait=*/false);
  if (const auto state = streams_.state()) host_.channel->send(*state, nullptr, /*wait=*/false);
}

// Under mutex_: rcand ends the host; its reader then sees the channel close and the supervisor buries it.
void IsolatedCapability::kill_host(const std::string& why) {
  if (host_.pid == 0 || !kill_reason_.empty()) return;
  kill_reason_ = why;
  ::kill(host_.pid, SIGKILL);
}

// Under mutex_: a host whose channel closed. Its actuators halted first, then the process reaped and the death
// reported; the next host starts after the backoff, unless this was a crash loop.
void IsolatedCapability::bury(std::unique_lock<std::mutex>& lock) {
  Host host = std::move(host_);
  host_ = {};
  up_ = false;  // new requests answer 503 from now on; those waiting on it once it is reaped, with the reason
  down_reason_ = "its process " + std::to_string(host.pid) + " ended";
  const std::set<std::string> moved = moved_;
  lock.unlock();
  obstacles_.lost();
  credentials_.clear();
  halt_moved(moved);
  calls_.post([this, moved] { halt_moved(moved); });  // again after any call of the dead host already under way
  const std::string how = close_and_reap(host);
  lock.lock();
  const auto now = Clock::now();
  const std::string process = "its process " + std::to_string(host.pid);
  down_reason_ = !kill_reason_.empty()   ? process + " " + kill_reason_ + ", and rcand killed it"
                 : !start_error_.empty() ? "its capability did not start in " + process.substr(4) + ": " + start_error_
                                         : process + " " + how;
  ++generation_;
  changed_.notify_all();  // the requests waiting on it answer 503 now, with the reason
  if (!route_specs_) {    // it never started: the capability's start failed, as it would have in process
    failed_ = true;
    return;
  }
  deaths_.push_back(now);
  while (!deaths_.empty() && now - deaths_.front() > kCrashLoopWindow) deaths_.pop_front();
  backoff_ = now - host.started > kStableLife || backoff_.count() == 0 ? kFirstBackoff : std::min(backoff_ * 2, kMaxBackoff);
  restart_at_ = now + backoff_;
  const bool crash_loop = static_cast<int>(deaths_.size()) >= kCrashLoopDeaths;
  if (crash_loop) {
    failed_ = true;
    down_reason_ = "crash loop: " + std::to_string(deaths_.size()) + " deaths within " +
                   std::to_string(kCrashLoopWindow.count()) + " s; the last: " + down_reason_;
  }
  const std::string reason = down_reason_;
  const json fault = down_status();
  const sdk::Response unavailable_now = unavailable();
  lock.unlock();
  streams_.end_all(unavailable_now);
  context_.publish_status(fault);
  logger("kernel.plugins")
      ->error("capability {} ({}): {}{}", context_.instance_id(), spec_.plugin_id, reason,
              crash_loop ? "; not started again until rcand restarts" : "; restarting in " + ms_text(backoff_));
  if (events_.audit) events_.audit("isolated capability " + std::string(context_.instance_id()) + " process died", reason);
  if (crash_loop && events_.fail) events_.fail(reason);
  lock.lock();
}

json IsolatedCapability::with_pose(json message) const {
  if (const auto* pose = sdk::find<sdk::PoseSource>(context_)) message["pose"] = encode_pose(pose->read());
  return message;
}

void IsolatedCapability::halt_moved(const std::set<std::string>& moved) noexcept {
  for (const auto& id : moved) context_.motion().halt(id);
}

void IsolatedCapability::shutdown() noexcept {
  {
    std::lock_guard lock(mutex_);
    if (stopping_) return;
    stopping_ = true;
  }
  changed_.notify_all();
  if (supervisor_.joinable()) supervisor_.join();  // it ends the host first
  calls_.join();
}

// Under mutex_, on the supervisor, as it ends: the capability's own shutdown() in the host, given 1500 ms, then the
// process ended and reaped. Here because the host dies with the thread that started it (PR_SET_PDEATHSIG).
void IsolatedCapability::end_host(std::unique_lock<std::mutex>& lock) {
  if (host_.pid == 0) return;
  host_.channel->send({{"t", "shutdown"}}, nullptr, /*wait=*/false);
  if (!changed_.wait_for(lock, std::chrono::milliseconds(1500), [&] { return host_.gone; }))
    kill_host("did not shut down within 1500 ms");
  Host host = std::move(host_);
  host_ = {};
  up_ = false;
  lock.unlock();
  close_and_reap(host);
  streams_.end_all(sdk::Response::error(503, "UNAVAILABLE", "rcand is shutting down"));
  lock.lock();
}

// Not under mutex_ (its reader may want it one last time): the channel closed, the reader joined, the process reaped.
std::string IsolatedCapability::close_and_reap(Host& host) {
  host.channel->shutdown();
  if (host.reader.joinable()) host.reader.join();
  return reap(host.pid);
}

}  // namespace rcand::isolation
