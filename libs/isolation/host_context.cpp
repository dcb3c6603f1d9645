#include "libs/isolation/host_context.hpp"

#include <utility>

#include "libs/base/logging.hpp"

namespace rcand::isolation {

using nlohmann::json;

namespace {

std::vector<sdk::ActuatorInfo> actuators_of(const json& start) {
  std::vector<sdk::ActuatorInfo> actuators;
  for (const auto& entry : start.at("actuators"))
    actuators.push_back({entry.at(0).get<std::string>(), entry.at(1).get<std::string>()});
  return actuators;
}

}  // namespace

HostContext::HostContext(Channel& channel, const json& start)
    : channel_(channel),
      plugin_id_(start.at("plugin").get<std::string>()),
      instance_id_(start.at("capability").get<std::string>()),
      gate_(*this, actuators_of(start)),
      settings_(start.at("settings")),
      robot_config_(start.at("robot_config")),
      latched_(start.value("latched", false)) {
  pose_.update(start);
}

HostContext::~HostContext() { join_workers(); }

sdk::Worker& HostContext::worker(std::string_view name) {
  if (name.empty()) throw std::invalid_argument("a worker needs a name");
  const std::string full = instance_id_ + "." + std::string(name);
  std::lock_guard lock(mutex_);
  for (auto& worker : workers_)
    if (worker->name() == full) return *worker;
  workers_.push_back(
      std::make_unique<WorkerThread>(full, [this, full](const std::string& why) { logger_.error("worker ", full, ": ", why); }));
  return *workers_.back();
}

void HostContext::publish_status(const json& status) noexcept { channel_.send({{"t", "publish"}, {"status", status}}); }

const void* HostContext::service(std::string_view interface_id) const noexcept {
  if (interface_id == sdk::Metrics::kServiceId) return static_cast<const sdk::Metrics*>(&metrics_);
  if (interface_id == sdk::RequestDispatcher::kServiceId) return static_cast<const sdk::RequestDispatcher*>(&dispatcher_);
  if (interface_id == sdk::PoseSource::kServiceId && pose_.known()) return static_cast<const sdk::PoseSource*>(&pose_);
  std::lock_guard lock(mutex_);
  const auto it = local_services_.find(interface_id);
  return it != local_services_.end() ? it->second : nullptr;
}

bool HostContext::offer_service(std::string_view interface_id, const void* service) noexcept {
  if (interface_id == sdk::ObstacleSource::kServiceId && service != nullptr) {
    try {
      const json reply = call("offer", "", interface_id, nullptr);
      if (reply.value("result", json()) != true) return false;  // refused by rcand (another plugin offers it), logged there
      std::lock_guard lock(mutex_);
      if (!obstacles_) obstacles_ = std::make_unique<ObstaclePoller>(channel_, *static_cast<const sdk::ObstacleSource*>(service));
      return true;
    } catch (const std::exception& e) {
      logger_.error("obstacle source not offered: ", e.what());
      return false;
    }
  }
  if (interface_id.empty() || service == nullptr) return false;
  // Found by this plugin itself (chat's own brains in its chain), not by rcand or other plugins: not carried.
  std::lock_guard lock(mutex_);
  if (!local_services_.emplace(std::string(interface_id), service).second) return false;
  logger_.info("service ", interface_id, " offered within its own process only: other plugins do not find it");
  return true;
}

void HostContext::set_latched(bool latched) {
  {
    std::lock_guard lock(mutex_);
    latched_.store(latched);
  }
  changed_.notify_all();
}

void HostContext::deliver(const json& reply) {
  {
    std::lock_guard lock(mutex_);
    if (auto it = calls_.find(reply.at("id").get<std::uint64_t>()); it != calls_.end()) it->second = reply;
  }
  changed_.notify_all();
}

void HostContext::close() {
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
  }
  changed_.notify_all();
  dispatcher_.close();
}

void HostContext::join_workers() {
  std::deque<std::unique_ptr<WorkerThread>> workers;
  {
    std::lock_guard lock(mutex_);
    workers.swap(workers_);
  }
  for (auto& worker : workers) worker->join();
  dispatcher_.join();
  std::unique_ptr<ObstaclePoller> obstacles;
  {
    std::lock_guard lock(mutex_);
    obstacles.swap(obstacles_);
  }
}

json HostContext::call(std::string_view op, std::string_view actuator, std::string_view method, json args) {
  std::unique_lock lock(mutex_);
  const std::uint64_t id = ++next_call_;
  calls_[id];
  lock.unlock();
  const bool sent = channel_.send(
      {{"t", "call"}, {"id", id}, {"op", op}, {"actuator", actuator}, {"method", method}, {"args", std::move(args)}});
  lock.lock();
  if (sent) changed_.wait(lock, [&] { return calls_[id].has_value() || closed_; });
  auto reply = std::move(calls_[id]);
  calls_.erase(id);
  if (reply) return std::move(*reply);
  return {{"gate", static_cast<int>(sdk::GateStatus::ActuatorFailed)}, {"error", "rcand did not answer: its channel is closed"}};
}

void HostContext::Log::log(sdk::LogLevel level, std::string_view message) noexcept {
  // Never waits: a line rcand cannot take now (its channel full) is dropped rather than holding the plugin.
  channel_.send({{"t", "log"}, {"level", static_cast<int>(level)}, {"text", message}}, nullptr, /*wait=*/false);
}

bool HostContext::Estop::sleep_unless_latched(std::chrono::microseconds duration) const {
  std::unique_lock lock(host_.mutex_);
  return !host_.changed_.wait_for(lock, duration, [&] { return host_.latched_.load(); });
}

void HostContext::Estop::request_estop(const std::string& reason) noexcept {
  try {
    host_.call("estop", "", "", reason);
  } catch (...) {  // noexcept hook: a reason that cannot be encoded still latches nothing here; rcand's own checks stand
  }
}

sdk::GateStatus HostContext::Gate::through_stand_in(std::string_view actuator_id, std::string_view op,
                                                    const std::function<void(sdk::ActuatorDriver&)>& use) const {
  for (const auto& info : actuators_) {
    if (info.id != actuator_id) continue;
    const std::string id(actuator_id);
    auto outcome = std::make_shared<CallOutcome>();
    auto actuator = remote_actuator(
        info.interface, op,
        [this, id](std::string_view call_op, std::string_view method, json args) {
          return host_.call(call_op, id, method, std::move(args));
        },
        outcome);
    if (!actuator) {
      host_.logger_.error("actuator ", actuator_id, " implements ", info.interface,
                          ", which is not carried to an isolated capability yet: run this capability in_process");
      return sdk::GateStatus::WrongInterface;
    }
    use(*actuator);
    return outcome->status;
  }
  return sdk::GateStatus::UnknownActuator;
}

sdk::GateStatus HostContext::Gate::actuate(std::string_view actuator_id,
                                           const std::function<void(sdk::ActuatorDriver&)>& command) {
  return through_stand_in(actuator_id, "actuate", command);
}

sdk::GateStatus HostContext::Gate::inspect(std::string_view actuator_id,
                                           const std::function<void(const sdk::ActuatorDriver&)>& reader) const {
  return through_stand_in(actuator_id, "inspect", [&reader](const sdk::ActuatorDriver& actuator) { reader(actuator); });
}

void HostContext::Gate::halt(std::string_view actuator_id) noexcept {
  try {
    host_.call("halt", actuator_id, "halt", json::array());
  } catch (...) {  // noexcept: rcand halts what this capability moved when its process ends
  }
}

}  // namespace rcand::isolation
