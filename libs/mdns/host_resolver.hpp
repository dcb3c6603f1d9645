// Resolves mDNS host names ("alex.local") for the swarm through avahi-daemon (avahi_host_name_resolver), on its
// own Avahi thread, with a short lookup timeout and a cache, so a broadcast stop spends its per-peer budget on the
// stop and not on resolution: known hosts answer from the cache at once; an unknown or absent host is remembered
// briefly as unresolvable, so the static `ip` fallback is taken at once next time. Without avahi-daemon every
// lookup fails at once ("mDNS unavailable") and the fallback applies.
#pragma once

#include <spdlog/logger.h>

#include <atomic>
#include <chrono>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "libs/base/host_resolver.hpp"
#include "libs/mdns/avahi_connection.hpp"

struct AvahiHostNameResolver;
struct AvahiWatch;

namespace rcand::mdns {

struct HostResolverOptions {
  std::chrono::milliseconds lookup_timeout{1000};  // one avahi lookup, then the host counts as unresolvable
  std::chrono::milliseconds positive_ttl{60000};   // a resolved address is reused this long
  std::chrono::milliseconds negative_ttl{5000};    // an unresolvable host is not asked again this long
};

// "*.local" (any case, optional trailing dot).
bool is_mdns_host(std::string_view host) noexcept;

class AvahiHostResolver final : public HostResolver {
 public:
  explicit AvahiHostResolver(std::shared_ptr<spdlog::logger> log, HostResolverOptions options = {});
  ~AvahiHostResolver() override;  // stop()
  AvahiHostResolver(const AvahiHostResolver&) = delete;
  AvahiHostResolver& operator=(const AvahiHostResolver&) = delete;

  // Starts the Avahi thread. Lookups before start() fail at once.
  void start();
  // Fails pending lookups ("resolver stopped") and joins the thread. Idempotent.
  void stop() noexcept;

  bool handles(std::string_view host) const override { return is_mdns_host(host); }
  void resolve(const std::string& host, Done done) override;
  // Resolves in the background to fill the cache (startup: the swarm's hosts).
  void prefetch(const std::vector<std::string>& hosts);

  struct Lookup;  // one host being resolved on the Avahi thread

 private:
  struct CacheEntry {
    std::vector<std::string> addresses;
    std::string why;
    std::chrono::steady_clock::time_point expires;
  };
  friend struct AvahiHostResolverCallbacks;                                                   // Avahi's C callbacks
  void start_queued();                                                                        // Avahi thread
  void finish(const std::string& host, std::vector<std::string> addresses, std::string why);  // any thread
  void cancel_lookups(const std::string& why);                                                // Avahi thread

  std::shared_ptr<spdlog::logger> log_;
  HostResolverOptions options_;
  std::unique_ptr<AvahiConnection> connection_;
  int wake_fd_ = -1;
  AvahiWatch* wake_watch_ = nullptr;
  std::atomic<bool> started_{false};  // the wake-up watch exists: lookups can be queued
  std::mutex mutex_;                  // cache_, waiters_, queue_
  std::map<std::string, CacheEntry> cache_;
  std::map<std::string, std::vector<Done>> waiters_;        // hosts being resolved, with whoever waits for them
  std::deque<std::string> queue_;                           // hosts to start resolving on the Avahi thread
  std::map<std::string, std::unique_ptr<Lookup>> lookups_;  // Avahi thread only
};

}  // namespace rcand::mdns
