// Publishes this robot as a DNS-SD service (docs/protocol.md §5: `_rcan._tcp`, instance name metadata.robot_name, the bound
// port, the registry's TXT record) through avahi-daemon, and keeps it published: the TXT record is re-read about
// once a second (and at once on refresh_soon(), e.g. when the e-stop latches) and updated when it changed; a name
// taken on the network is replaced the Avahi way (avahi_alternative_service_name) and logged; after an avahi-daemon
// restart the service is registered again. stop() withdraws it (the daemon sends the goodbye).
#pragma once

#include <spdlog/logger.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "libs/mdns/avahi_connection.hpp"

struct AvahiEntryGroup;
struct AvahiWatch;

namespace rcand::mdns {

struct ServiceSpec {
  std::string name;  // the instance name wanted (metadata.robot_name)
  std::string type = "_rcan._tcp";
  std::uint16_t port = 0;
  // The TXT record now: called on the publisher's thread, must be cheap and must not block.
  std::function<std::map<std::string, std::string>()> txt;
  std::chrono::milliseconds refresh = std::chrono::seconds(1);
};

class ServicePublisher {
 public:
  explicit ServicePublisher(std::shared_ptr<spdlog::logger> log);
  ~ServicePublisher();  // stop()
  ServicePublisher(const ServicePublisher&) = delete;
  ServicePublisher& operator=(const ServicePublisher&) = delete;

  // Starts the Avahi thread and registers whenever avahi-daemon serves. Once.
  void start(ServiceSpec spec);
  // Any thread, never blocks (one write to an eventfd): re-read the TXT record now. Safe before start().
  void refresh_soon() noexcept;
  // Withdraws the service and joins the thread. Idempotent.
  void stop() noexcept;
  // The instance name in use (after collisions); empty until first registered.
  std::string published_name() const;

 private:
  friend struct ServicePublisherCallbacks;  // Avahi's C callbacks
  void handle_group(AvahiEntryGroup* group, int state);
  void handle_tick(struct AvahiTimeout* timeout);
  void register_service(AvahiClient* client);
  void add_and_commit();
  void take_alternative_name(const char* why);
  void refresh_txt();
  void free_group();

  std::shared_ptr<spdlog::logger> log_;
  std::unique_ptr<AvahiConnection> connection_;
  ServiceSpec spec_;
  int nudge_fd_ = -1;  // eventfd: refresh_soon() from any thread wakes the poll thread
  AvahiWatch* nudge_watch_ = nullptr;
  struct AvahiTimeout* tick_ = nullptr;
  AvahiEntryGroup* group_ = nullptr;
  bool committed_ = false;
  std::map<std::string, std::string> published_txt_;
  mutable std::mutex name_mutex_;  // name_ is read by published_name() from other threads
  std::string name_;
  bool established_logged_ = false;
};

}  // namespace rcand::mdns
