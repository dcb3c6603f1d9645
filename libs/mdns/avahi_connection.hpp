// One connection to avahi-daemon over the system D-Bus that outlives the daemon (and the bus) coming and going.
// It owns an AvahiThreadedPoll (its own thread: never an HTTP I/O thread) and a client made with
// AVAHI_CLIENT_NO_FAIL. Avahi's client states drive it: CONNECTING waits for the daemon, S_RUNNING hands the client
// to the user (again after every outage), S_REGISTERING/S_COLLISION interrupt what was published, and FAILURE
// (the daemon or the bus went away) frees the client and makes a new one; when even the bus is missing, it retries
// on a timer. Each outage is logged once, and its end once.
#pragma once

#include <spdlog/logger.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <string>

struct AvahiClient;
struct AvahiPoll;
struct AvahiThreadedPoll;
struct AvahiTimeout;

namespace rcand::mdns {

class AvahiConnection {
 public:
  // Every event runs on the poll thread with the poll lock held.
  struct Events {
    std::function<void(AvahiClient*)> running;  // the daemon serves (first time or again): (re)create entries
    std::function<void()> interrupted;          // entries were withdrawn by the daemon (host rename, waiting)
    std::function<void()> lost;                 // the client is about to be freed: drop every object made on it
    // Once, in start(), before the poll thread runs: the place to create watches and timers. (Avahi's simple poll
    // asserts when a watch is added from another thread while it dispatches, even under the lock.)
    std::function<void(const AvahiPoll*)> prepare;
  };

  // `what` names the user in logs ("publisher", "resolver").
  AvahiConnection(std::string what, std::shared_ptr<spdlog::logger> log, Events events,
                  std::chrono::milliseconds bus_retry = std::chrono::seconds(2));
  ~AvahiConnection();  // stop()
  AvahiConnection(const AvahiConnection&) = delete;
  AvahiConnection& operator=(const AvahiConnection&) = delete;

  // Makes the first client and starts the thread. Returns false (logged) only when the poll itself cannot start.
  bool start();
  // Runs `lost`, frees the client (avahi-daemon withdraws what it published) and joins the thread. Idempotent.
  // Never call it from the poll thread.
  void stop() noexcept;

  // Runs `fn` with the poll lock held, from any thread but the poll thread (blocks while a poll callback runs).
  void locked(const std::function<void()>& fn);
  // Poll thread (or locked) only: the poll API for timers and watches, and the current client (null when none).
  const AvahiPoll* poll_api() const noexcept;
  AvahiClient* client() const noexcept { return client_; }
  // Any thread: whether the daemon currently serves this client.
  bool running() const noexcept { return running_.load(); }

 private:
  friend struct AvahiConnectionCallbacks;  // Avahi's C callbacks (their signatures need Avahi's enums)
  static void on_retry(AvahiTimeout* timeout, void* self);
  void handle_state(AvahiClient* client, int state);
  void make_client();
  void drop_client();
  void arm_retry(std::chrono::milliseconds delay);
  void report_outage(const std::string& why);

  std::string what_;
  std::shared_ptr<spdlog::logger> log_;
  Events events_;
  std::chrono::milliseconds bus_retry_;
  AvahiThreadedPoll* poll_ = nullptr;
  AvahiClient* client_ = nullptr;
  AvahiTimeout* retry_ = nullptr;
  std::atomic<bool> running_{false};
  bool outage_logged_ = false;
  bool ever_running_ = false;
  bool stopped_ = false;
};

}  // namespace rcand::mdns
