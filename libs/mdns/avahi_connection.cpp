#include "libs/mdns/avahi_connection.hpp"

#include <avahi-client/client.h>
#include <avahi-common/error.h>
#include <avahi-common/thread-watch.h>
#include <avahi-common/timeval.h>

namespace rcand::mdns {

struct AvahiConnectionCallbacks {
  static void on_state(AvahiClient* client, AvahiClientState state, void* self) {
    static_cast<AvahiConnection*>(self)->handle_state(client, state);
  }
};

AvahiConnection::AvahiConnection(std::string what, std::shared_ptr<spdlog::logger> log, Events events,
                                 std::chrono::milliseconds bus_retry)
    : what_(std::move(what)), log_(std::move(log)), events_(std::move(events)), bus_retry_(bus_retry) {}

AvahiConnection::~AvahiConnection() { stop(); }

bool AvahiConnection::start() {
  if (poll_ != nullptr) return true;
  poll_ = avahi_threaded_poll_new();
  if (poll_ == nullptr) {
    log_->error("mDNS {}: cannot create the Avahi event loop; mDNS is off", what_);
    return false;
  }
  if (events_.prepare) events_.prepare(poll_api());
  make_client();  // callbacks may run right here, before the thread exists
  if (avahi_threaded_poll_start(poll_) < 0) {
    log_->error("mDNS {}: cannot start the Avahi event loop thread; mDNS is off", what_);
    drop_client();
    avahi_threaded_poll_free(poll_);
    poll_ = nullptr;
    return false;
  }
  return true;
}

void AvahiConnection::stop() noexcept {
  if (poll_ == nullptr || stopped_) return;
  avahi_threaded_poll_lock(poll_);
  stopped_ = true;
  if (retry_) {
    poll_api()->timeout_free(retry_);
    retry_ = nullptr;
  }
  drop_client();
  avahi_threaded_poll_unlock(poll_);
  avahi_threaded_poll_stop(poll_);
  avahi_threaded_poll_free(poll_);
  poll_ = nullptr;
}

void AvahiConnection::locked(const std::function<void()>& fn) {
  if (poll_ == nullptr) return;
  avahi_threaded_poll_lock(poll_);
  try {
    if (!stopped_) fn();
  } catch (...) {
    avahi_threaded_poll_unlock(poll_);
    throw;
  }
  avahi_threaded_poll_unlock(poll_);
}

const AvahiPoll* AvahiConnection::poll_api() const noexcept { return avahi_threaded_poll_get(poll_); }

void AvahiConnection::make_client() {
  int error = 0;
  // NO_FAIL: no daemon yet means CONNECTING (it is waited for), not an error. A missing system bus still fails.
  AvahiClient* made = avahi_client_new(poll_api(), AVAHI_CLIENT_NO_FAIL, &AvahiConnectionCallbacks::on_state, this, &error);
  if (made == nullptr) {
    report_outage(std::string("cannot reach the system D-Bus (") + avahi_strerror(error) + ")");
    arm_retry(bus_retry_);
    return;
  }
  client_ = made;
}

void AvahiConnection::drop_client() {
  running_ = false;
  if (client_ == nullptr) return;
  if (events_.lost) events_.lost();
  avahi_client_free(client_);
  client_ = nullptr;
}

void AvahiConnection::arm_retry(std::chrono::milliseconds delay) {
  timeval when{};
  avahi_elapse_time(&when, static_cast<unsigned>(delay.count()), 0);
  if (retry_) poll_api()->timeout_update(retry_, &when);
  else retry_ = poll_api()->timeout_new(poll_api(), &when, &AvahiConnection::on_retry, this);
}

void AvahiConnection::on_retry(AvahiTimeout* timeout, void* self) {
  auto* connection = static_cast<AvahiConnection*>(self);
  connection->poll_api()->timeout_update(timeout, nullptr);  // disarmed until needed again
  if (connection->stopped_) return;
  // A failed client is freed here, outside its own callback, then replaced.
  connection->drop_client();
  connection->make_client();
}

void AvahiConnection::report_outage(const std::string& why) {
  if (outage_logged_) return;
  outage_logged_ = true;
  log_->warn("mDNS {}: {}; rcand keeps serving HTTP and waits for avahi-daemon", what_, why);
}

void AvahiConnection::handle_state(AvahiClient* client, int state) {
  client_ = client;  // also during avahi_client_new, before it returned
  switch (static_cast<AvahiClientState>(state)) {
    case AVAHI_CLIENT_S_RUNNING:
      running_ = true;
      if (outage_logged_ || ever_running_) log_->info("mDNS {}: avahi-daemon is available again", what_);
      outage_logged_ = false;
      ever_running_ = true;
      if (events_.running) events_.running(client);
      break;
    case AVAHI_CLIENT_S_REGISTERING:
    case AVAHI_CLIENT_S_COLLISION:
      running_ = false;
      if (events_.interrupted) events_.interrupted();
      break;
    case AVAHI_CLIENT_CONNECTING:
      running_ = false;
      report_outage("avahi-daemon is not running");
      if (events_.interrupted) events_.interrupted();
      break;
    case AVAHI_CLIENT_FAILURE:
      running_ = false;
      report_outage(std::string("lost avahi-daemon (") + avahi_strerror(avahi_client_errno(client)) + ")");
      arm_retry(std::chrono::milliseconds(0));  // free and re-create outside this callback
      break;
  }
}

}  // namespace rcand::mdns
