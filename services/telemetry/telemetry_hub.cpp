#include "services/telemetry/telemetry_hub.hpp"

#include <pthread.h>

#include <vector>

#include "kernel/auth/slots.hpp"
#include "libs/base/logging.hpp"
#include "services/telemetry/telemetry_connection.hpp"

namespace rcand::services::telemetry {

namespace {

constexpr std::string_view kTelemetryPath = "/ws/telemetry";

constexpr kernel::SlotWords kTelemetrySlots{"telemetry WebSocket connections", "runtime.telemetry.max_clients",
                                            "runtime.telemetry.max_clients_per_principal",
                                            "runtime.telemetry.max_clients_per_address", "runtime.telemetry.reserved_clients"};

SlotLimits slot_limits(const HubOptions& options) {
  return {options.max_clients, options.reserved_clients, options.max_clients_per_principal, options.max_clients_per_address};
}

}  // namespace

TelemetryHub::TelemetryHub(HubOptions options, const kernel::Authenticator& auth, kernel::Api& api, BuildFrame build)
    : options_(options), auth_(auth), api_(api), build_(std::move(build)), slots_(slot_limits(options)) {}

TelemetryHub::~TelemetryHub() { stop(); }

http::UpgradeHandler TelemetryHub::upgrade_handler() {
  return [weak = weak_from_this()](const http::Request& request) -> http::UpgradeVerdict {
    if (request.path != kTelemetryPath) return {};  // another service's path, or nobody's
    http::UpgradeVerdict verdict;
    auto hub = weak.lock();
    if (!hub) {
      verdict.refuse = http::error_response(503, "UNAVAILABLE", "telemetry is not running");
      return verdict;
    }
    // Authenticated like HTTP (docs/protocol.md §3): the bearer header, or ?token= where a browser cannot set one.
    std::optional<std::string_view> bearer;
    if (auto header = request.header("authorization")) bearer = kernel::bearer_token(*header);
    else if (auto token = request.query.find("token"); token != request.query.end()) bearer = token->second;
    const auto now_s =
        std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
    const std::uint64_t generation = hub->auth_.generation();  // before: a reload in between is re-checked
    auto outcome = hub->auth_.authorize(bearer, sdk::Scope::Status, now_s);
    if (auto* failure = std::get_if<kernel::AuthError>(&outcome)) {
      hub->stats_.refused.fetch_add(1);
      verdict.refuse = http::error_response(failure->status, failure->code, failure->message);
      return verdict;
    }
    const auto& principal = std::get<kernel::Principal>(outcome);
    bool stopped = false;
    {
      std::lock_guard lock(hub->clients_mutex_);
      stopped = hub->stopped_;
    }
    // The slot is the upgrade's from here, the connection's once taken: given back when both are gone, so an upgrade
    // the server drops after this hook does not leak it.
    const SlotHolder holder =
        kernel::slot_holder(principal.name, principal.role, principal.via == "open", http::client_address(request.remote));
    auto claim = stopped ? SlotTable::Claim{} : hub->slots_.claim(holder);
    if (!claim.slot) {
      hub->stats_.refused.fetch_add(1);
      verdict.refuse = stopped ? http::error_response(503, "UNAVAILABLE", "telemetry is not running")
                               : kernel::slot_refusal(claim, kTelemetrySlots, holder, principal.role);
      if (stopped) verdict.refuse->headers.emplace_back("Retry-After", "5");
      return verdict;
    }
    auto slot = std::move(claim.slot);
    Credential credential{std::string(bearer.value_or("")), principal.name, principal.expires_s, generation};
    verdict.take = [weak, credential, slot](http::Upgraded&& upgraded) {
      auto taker = weak.lock();
      if (!taker) return;
      auto connection = std::make_shared<Connection>(weak, std::move(upgraded.stream), upgraded.request.remote, credential, slot);
      {
        std::lock_guard lock(taker->clients_mutex_);
        if (taker->stopped_) return;  // the connection closes as it goes out of scope
        taker->clients_.insert(connection);
      }
      taker->stats_.accepted.fetch_add(1);
      connection->accept(std::move(upgraded.raw));
    };
    return verdict;
  };
}

void TelemetryHub::start() {
  std::lock_guard lock(wake_mutex_);
  if (ticker_.joinable() || stopping_) return;
  ticker_ = std::thread([this] { run(); });
}

void TelemetryHub::signal(HubEvent event) noexcept {
  {
    std::lock_guard lock(wake_mutex_);
    events_ |= static_cast<unsigned>(event);
  }
  wake_.notify_one();
}

// Frames on an absolute schedule (start + n * period), so a slow build or a push never shifts the ones after it.
void TelemetryHub::run() noexcept {
  pthread_setname_np(pthread_self(), "telemetry");
  using Clock = std::chrono::steady_clock;
  auto next = Clock::now() + options_.period;
  std::unique_lock lock(wake_mutex_);
  while (!stopping_) {
    wake_.wait_until(lock, next, [this] { return stopping_ || events_ != 0; });
    if (stopping_) break;
    const unsigned events = std::exchange(events_, 0u);
    const auto now = Clock::now();
    const bool due = now >= next;
    if (due) {
      next += options_.period;
      if (next <= now) next = now + options_.period;  // fell behind (suspended): no burst of late frames
    }
    lock.unlock();
    // A latch wins over a clear in the same wake-up: the frame shows the latch as it is when built either way.
    if (events & static_cast<unsigned>(HubEvent::Latched)) publish("estop_latched");
    else if (events & static_cast<unsigned>(HubEvent::Cleared)) publish("estop_cleared");
    if (due) publish("tick");
    lock.lock();
  }
}

void TelemetryHub::publish(std::string_view event) noexcept {
  std::vector<std::shared_ptr<Connection>> targets;
  try {
    {
      std::lock_guard lock(clients_mutex_);
      if (stopped_ || clients_.empty()) return;  // nobody watches: nothing is built
      targets.assign(clients_.begin(), clients_.end());
    }
    auto frame = std::make_shared<const std::string>(build_(++seq_, event));  // once, shared by every client
    stats_.frames_built.fetch_add(1, std::memory_order_relaxed);
    for (const auto& connection : targets) connection->offer(frame);
  } catch (const std::exception& e) {
    logger("telemetry")->error("telemetry frame failed: {}", e.what());
  }
}

void TelemetryHub::closed(const std::shared_ptr<Connection>& connection) noexcept {
  std::lock_guard lock(clients_mutex_);
  clients_.erase(connection);
}

void TelemetryHub::stop() noexcept {
  {
    std::lock_guard lock(wake_mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (ticker_.joinable() && ticker_.get_id() != std::this_thread::get_id()) ticker_.join();
  std::set<std::shared_ptr<Connection>> open;
  {
    std::lock_guard lock(clients_mutex_);
    stopped_ = true;
    open.swap(clients_);
  }
  for (const auto& connection : open) {
    try {
      connection->close();
    } catch (...) {  // its loop is gone: the connection dies with it
    }
  }
}

HubCounters TelemetryHub::counters() const {
  HubCounters c;
  {
    std::lock_guard lock(clients_mutex_);
    c.clients = clients_.size();
  }
  c.accepted = stats_.accepted.load();
  c.refused = stats_.refused.load();
  c.frames_built = stats_.frames_built.load();
  c.frames_sent = stats_.frames_sent.load();
  c.frames_replaced = stats_.frames_replaced.load();
  c.dropped_slow = stats_.dropped_slow.load();
  c.closed_credential = stats_.closed_credential.load();
  c.stops = stats_.stops.load();
  c.bad_messages = stats_.bad_messages.load();
  return c;
}

}  // namespace rcand::services::telemetry
