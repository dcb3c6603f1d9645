#include "libs/mdns/host_resolver.hpp"

#include <avahi-client/lookup.h>
#include <avahi-common/address.h>
#include <avahi-common/error.h>
#include <avahi-common/timeval.h>
#include <avahi-common/watch.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>

namespace rcand::mdns {

bool is_mdns_host(std::string_view host) noexcept {
  if (!host.empty() && host.back() == '.') host.remove_suffix(1);
  constexpr std::string_view kSuffix = ".local";
  if (host.size() <= kSuffix.size()) return false;
  const auto tail = host.substr(host.size() - kSuffix.size());
  return std::equal(tail.begin(), tail.end(), kSuffix.begin(),
                    [](char a, char b) { return std::tolower(static_cast<unsigned char>(a)) == b; });
}

namespace {

std::string normalized(std::string host) {
  if (!host.empty() && host.back() == '.') host.pop_back();
  for (char& c : host) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return host;
}

const char* const kUnavailable = "mDNS unavailable (avahi-daemon not running)";

}  // namespace

struct AvahiHostResolver::Lookup {
  AvahiHostNameResolver* resolver = nullptr;
  AvahiTimeout* timeout = nullptr;
  std::function<void(std::vector<std::string>, std::string)> complete;  // Avahi thread; frees this Lookup
};

namespace {

void on_found(AvahiHostNameResolver*, AvahiIfIndex, AvahiProtocol, AvahiResolverEvent event, const char*,
              const AvahiAddress* address, AvahiLookupResultFlags, void* userdata) {
  auto* lookup = static_cast<AvahiHostResolver::Lookup*>(userdata);
  if (event == AVAHI_RESOLVER_FOUND && address != nullptr) {
    char text[AVAHI_ADDRESS_STR_MAX];
    avahi_address_snprint(text, sizeof text, address);
    lookup->complete({text}, {});
  } else {
    lookup->complete({}, "not found through mDNS");
  }
}

void on_lookup_timeout(AvahiTimeout*, void* userdata) {
  static_cast<AvahiHostResolver::Lookup*>(userdata)->complete({}, "no mDNS answer in time");
}

}  // namespace

struct AvahiHostResolverCallbacks {
  static void on_wake(AvahiWatch*, int fd, AvahiWatchEvent, void* self) {
    std::uint64_t count = 0;
    [[maybe_unused]] const auto drained = ::read(fd, &count, sizeof count);
    static_cast<AvahiHostResolver*>(self)->start_queued();
  }
};

AvahiHostResolver::AvahiHostResolver(std::shared_ptr<spdlog::logger> log, HostResolverOptions options)
    : log_(std::move(log)), options_(options), wake_fd_(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)) {
  AvahiConnection::Events events;
  // The client is about to be freed, and with it every resolver made on it: end those lookups first.
  events.lost = [this] { cancel_lookups("lost avahi-daemon"); };
  events.prepare = [this](const AvahiPoll* api) {
    if (wake_fd_ >= 0) wake_watch_ = api->watch_new(api, wake_fd_, AVAHI_WATCH_IN, &AvahiHostResolverCallbacks::on_wake, this);
  };
  connection_ = std::make_unique<AvahiConnection>("resolver", log_, std::move(events));
}

AvahiHostResolver::~AvahiHostResolver() {
  stop();
  if (wake_fd_ >= 0) ::close(wake_fd_);
}

void AvahiHostResolver::start() {
  if (!connection_->start()) return;
  started_ = wake_watch_ != nullptr;
}

void AvahiHostResolver::stop() noexcept {
  started_ = false;
  connection_->locked([this] {
    if (wake_watch_) connection_->poll_api()->watch_free(wake_watch_);
    wake_watch_ = nullptr;
  });
  connection_->stop();
  std::map<std::string, std::vector<Done>> waiting;
  {
    std::lock_guard lock(mutex_);
    waiting.swap(waiters_);
    queue_.clear();
  }
  for (auto& [host, dones] : waiting)
    for (auto& done : dones) done({}, "resolver stopped");
}

void AvahiHostResolver::resolve(const std::string& host, Done done) {
  const std::string key = normalized(host);
  bool queued = false, wake = false;
  {
    std::unique_lock lock(mutex_);
    if (auto hit = cache_.find(key); hit != cache_.end() && hit->second.expires > std::chrono::steady_clock::now()) {
      auto addresses = hit->second.addresses;
      auto why = hit->second.why;
      lock.unlock();
      done(std::move(addresses), std::move(why));
      return;
    }
    if (connection_->running() && started_) {
      auto& waiting = waiters_[key];
      waiting.push_back(std::move(done));
      queued = true;
      if (waiting.size() == 1) {
        queue_.push_back(key);
        wake = true;
      }
    }
  }
  if (queued) {
    if (wake) {
      const std::uint64_t one = 1;
      [[maybe_unused]] const auto written = ::write(wake_fd_, &one, sizeof one);
    }
    return;
  }
  done({}, kUnavailable);
}

void AvahiHostResolver::prefetch(const std::vector<std::string>& hosts) {
  for (const auto& host : hosts)
    if (handles(host)) resolve(host, [](std::vector<std::string>, std::string) {});
}

void AvahiHostResolver::start_queued() {
  std::deque<std::string> hosts;
  {
    std::lock_guard lock(mutex_);
    hosts.swap(queue_);
  }
  for (const auto& host : hosts) {
    if (lookups_.count(host) != 0) continue;
    AvahiClient* client = connection_->client();
    if (client == nullptr || !connection_->running()) {
      finish(host, {}, kUnavailable);
      continue;
    }
    auto lookup = std::make_unique<Lookup>();
    Lookup* raw = lookup.get();
    raw->complete = [this, host, raw](std::vector<std::string> addresses, std::string why) {
      AvahiHostResolver* self = this;
      const std::string name = host;
      const AvahiPoll* api = self->connection_->poll_api();
      if (raw->resolver) avahi_host_name_resolver_free(raw->resolver);
      if (raw->timeout) api->timeout_free(raw->timeout);
      self->lookups_.erase(name);  // destroys *raw and this lambda's captures: only locals from here on
      self->finish(name, std::move(addresses), std::move(why));
    };
    // IPv4 addresses: an IPv6 link-local answer would need its interface, which a peer address does not carry.
    raw->resolver = avahi_host_name_resolver_new(client, AVAHI_IF_UNSPEC, AVAHI_PROTO_UNSPEC, host.c_str(), AVAHI_PROTO_INET,
                                                 AvahiLookupFlags(0), &on_found, raw);
    if (raw->resolver == nullptr) {
      finish(host, {}, std::string("cannot start an mDNS lookup: ") + avahi_strerror(avahi_client_errno(client)));
      continue;
    }
    timeval when{};
    avahi_elapse_time(&when, static_cast<unsigned>(options_.lookup_timeout.count()), 0);
    raw->timeout = connection_->poll_api()->timeout_new(connection_->poll_api(), &when, &on_lookup_timeout, raw);
    lookups_[host] = std::move(lookup);
  }
}

void AvahiHostResolver::cancel_lookups(const std::string& why) {
  while (!lookups_.empty()) {
    auto complete = lookups_.begin()->second->complete;  // a copy: the call destroys the original
    complete({}, why);
  }
}

void AvahiHostResolver::finish(const std::string& host, std::vector<std::string> addresses, std::string why) {
  std::vector<Done> waiting;
  {
    std::lock_guard lock(mutex_);
    const auto ttl = addresses.empty() ? options_.negative_ttl : options_.positive_ttl;
    cache_[host] = {addresses, why, std::chrono::steady_clock::now() + ttl};
    if (auto found = waiters_.find(host); found != waiters_.end()) {
      waiting = std::move(found->second);
      waiters_.erase(found);
    }
  }
  if (addresses.empty()) log_->debug("mDNS: cannot resolve {}: {}", host, why);
  else log_->debug("mDNS: {} is {}", host, addresses.front());
  for (auto& done : waiting) done(addresses, why);
}

}  // namespace rcand::mdns
