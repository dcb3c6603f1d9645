#include "kernel/plugins/instance_context.hpp"

#include <thread>

#include "rcand/sdk/r2r.hpp"
#include "rcand/sdk/services.hpp"

namespace rcand::kernel {

// inside_ is raised before sink_ is read and lowered after the sink returned (all seq_cst): once detach() stored
// null, a publish either reads null or is counted, so when the count is zero afterwards none is inside the sink.
void StatusSinkSlot::publish(const InstanceContext& from, const nlohmann::json& status) noexcept {
  inside_.fetch_add(1);
  if (StatusSink* sink = sink_.load()) sink->publish(from, status);
  inside_.fetch_sub(1);
}

void StatusSinkSlot::detach() noexcept {
  sink_.store(nullptr);
  while (inside_.load() != 0) std::this_thread::yield();
}

void InstanceEstop::request_estop(const std::string& reason) noexcept {
  const std::string source = "plugin " + plugin_id_ + " (" + instance_id_ + ")";
  std::uint64_t seq = 0;
  if (services_.audit != nullptr) {
    try {
      // A stop: the stops' retention, and a repeat while latched is counted into the entry it repeats.
      seq = services_.audit->begin_stop("plugin:" + plugin_id_, "", "estop requested by " + source, services_.estop.latched(),
                                        reason);
    } catch (...) {  // the audit entry is bookkeeping: the stop happens regardless
    }
  }
  services_.estop.latch(reason, source, {{}, "plugin", source, reason});
  if (seq != 0) {
    try {
      services_.audit->finish(seq, "ok", reason);
    } catch (...) {
    }
  }
}

InstanceContext::InstanceContext(std::string plugin_id, std::string instance_id, KernelServices& services,
                                 nlohmann::json settings, InstanceHealth& health)
    : plugin_id_(std::move(plugin_id)),
      instance_id_(std::move(instance_id)),
      services_(services),
      logger_(plugin_id_),
      settings_(std::move(settings)),
      health_(health) {}

InstanceContext::~InstanceContext() {
  withdraw_offers();
  join_workers();
}

bool InstanceContext::offer_service(std::string_view interface_id, const void* service) noexcept {
  try {
    return services_.directory.offer_service(interface_id, service, this, plugin_id_ + " (" + instance_id_ + ")", &health_);
  } catch (...) {  // no memory for the name: not offered
    return false;
  }
}

sdk::Worker& InstanceContext::worker(std::string_view name) {
  if (name.empty() || name.find_first_of(" /\t\n") != std::string_view::npos)
    throw std::invalid_argument("worker name must be a non-empty word");
  const std::string full = instance_id_ + "." + std::string(name);
  std::lock_guard lock(workers_mutex_);
  for (auto& worker : workers_)
    if (worker->name() == full) return *worker;
  // An exception escaping a worker task is plugin code failing: the instance goes out of service.
  return *workers_.emplace_back(std::make_unique<WorkerThread>(
      full, [this, full](const std::string& why) { health_.mark_failed("worker " + full + ": " + why); }));
}

// Deprecated (sdk/context.hpp): one link per instance, from the R2R service's sdk::R2rLinks when R2R runs here.
sdk::R2rLink* InstanceContext::r2r() noexcept {
  const auto* links = sdk::find<sdk::R2rLinks>(services_.directory);
  if (links == nullptr) return nullptr;
  std::lock_guard lock(r2r_mutex_);
  if (!r2r_link_) r2r_link_ = links->make_link(worker("r2r"), plugin_id_ + " (" + instance_id_ + ")");
  return r2r_link_.get();
}

void InstanceContext::join_workers() {
  std::lock_guard lock(workers_mutex_);
  for (auto& worker : workers_) worker->join();
}

}  // namespace rcand::kernel
