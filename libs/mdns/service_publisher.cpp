#include "libs/mdns/service_publisher.hpp"

#include <avahi-client/publish.h>
#include <avahi-common/alternative.h>
#include <avahi-common/error.h>
#include <avahi-common/malloc.h>
#include <avahi-common/timeval.h>
#include <avahi-common/watch.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include "libs/mdns/txt_list.hpp"

namespace rcand::mdns {
namespace {

// Local collisions (another client of the same daemon holds the name) answer add_service at once; bound the
// renaming so a broken daemon cannot spin us.
constexpr int kMaxRenames = 32;

const char* client_error(AvahiEntryGroup* group) {
  return avahi_strerror(avahi_client_errno(avahi_entry_group_get_client(group)));
}

}  // namespace

struct ServicePublisherCallbacks {
  static void on_group(AvahiEntryGroup* group, AvahiEntryGroupState state, void* self) {
    static_cast<ServicePublisher*>(self)->handle_group(group, state);
  }
  static void on_tick(AvahiTimeout* timeout, void* self) { static_cast<ServicePublisher*>(self)->handle_tick(timeout); }
  static void on_nudge(AvahiWatch*, int fd, AvahiWatchEvent, void* self) {
    std::uint64_t count = 0;
    [[maybe_unused]] const auto drained = ::read(fd, &count, sizeof count);
    static_cast<ServicePublisher*>(self)->refresh_txt();
  }
};

ServicePublisher::ServicePublisher(std::shared_ptr<spdlog::logger> log)
    : log_(std::move(log)), nudge_fd_(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)) {}

ServicePublisher::~ServicePublisher() {
  stop();
  if (nudge_fd_ >= 0) ::close(nudge_fd_);
}

void ServicePublisher::start(ServiceSpec spec) {
  if (connection_) return;
  spec_ = std::move(spec);
  {
    std::lock_guard lock(name_mutex_);
    name_ = spec_.name;
  }
  AvahiConnection::Events events;
  events.running = [this](AvahiClient* client) { register_service(client); };
  events.interrupted = [this] {
    // The daemon withdrew our entries (host name conflict, or it is gone): empty the group, re-add when it runs.
    if (group_ != nullptr) avahi_entry_group_reset(group_);
    committed_ = false;
  };
  events.lost = [this] { free_group(); };
  events.prepare = [this](const AvahiPoll* api) {
    timeval first{};
    avahi_elapse_time(&first, static_cast<unsigned>(spec_.refresh.count()), 0);
    tick_ = api->timeout_new(api, &first, &ServicePublisherCallbacks::on_tick, this);
    if (nudge_fd_ >= 0) nudge_watch_ = api->watch_new(api, nudge_fd_, AVAHI_WATCH_IN, &ServicePublisherCallbacks::on_nudge, this);
  };
  connection_ = std::make_unique<AvahiConnection>("publisher", log_, std::move(events));
  connection_->start();
}

void ServicePublisher::refresh_soon() noexcept {
  if (nudge_fd_ < 0) return;
  const std::uint64_t one = 1;
  [[maybe_unused]] const auto written = ::write(nudge_fd_, &one, sizeof one);  // EAGAIN: a nudge is pending anyway
}

void ServicePublisher::stop() noexcept {
  if (!connection_) return;
  bool was_published = false;
  connection_->locked([this, &was_published] {
    was_published = group_ != nullptr && committed_;
    const AvahiPoll* api = connection_->poll_api();
    if (tick_) api->timeout_free(tick_);
    if (nudge_watch_) api->watch_free(nudge_watch_);
    tick_ = nullptr;
    nudge_watch_ = nullptr;
  });
  connection_->stop();  // frees the group: avahi-daemon withdraws the service and sends the goodbye
  if (was_published) log_->info("mDNS: withdrew '{}' ({})", published_name(), spec_.type);
  connection_.reset();
}

std::string ServicePublisher::published_name() const {
  std::lock_guard lock(name_mutex_);
  return name_;
}

void ServicePublisher::register_service(AvahiClient* client) {
  if (group_ == nullptr) {
    group_ = avahi_entry_group_new(client, &ServicePublisherCallbacks::on_group, this);
    if (group_ == nullptr) {
      log_->error("mDNS: cannot create an Avahi entry group: {}", avahi_strerror(avahi_client_errno(client)));
      return;
    }
  }
  if (avahi_entry_group_is_empty(group_)) add_and_commit();
}

void ServicePublisher::add_and_commit() {
  published_txt_ = spec_.txt ? spec_.txt() : std::map<std::string, std::string>{};
  const TxtList txt = to_txt_list(published_txt_);
  for (int attempt = 0; attempt <= kMaxRenames; ++attempt) {
    const std::string name = published_name();
    const int added =
        avahi_entry_group_add_service_strlst(group_, AVAHI_IF_UNSPEC, AVAHI_PROTO_UNSPEC, AvahiPublishFlags(0), name.c_str(),
                                             spec_.type.c_str(), nullptr, nullptr, spec_.port, txt.get());
    if (added == AVAHI_ERR_COLLISION) {
      take_alternative_name("is already registered with this avahi-daemon");
      avahi_entry_group_reset(group_);
      continue;
    }
    if (added < 0) {
      log_->error("mDNS: cannot add service '{}' ({}): {}", name, spec_.type, avahi_strerror(added));
      return;
    }
    if (const int committed = avahi_entry_group_commit(group_); committed < 0) {
      log_->error("mDNS: cannot commit service '{}': {}", name, avahi_strerror(committed));
      return;
    }
    committed_ = true;
    return;
  }
  log_->error("mDNS: gave up after {} alternative names for '{}'", kMaxRenames, spec_.name);
}

void ServicePublisher::take_alternative_name(const char* why) {
  const std::string old_name = published_name();
  char* alternative = avahi_alternative_service_name(old_name.c_str());
  if (alternative == nullptr) return;
  {
    std::lock_guard lock(name_mutex_);
    name_ = alternative;
  }
  log_->warn("mDNS: service name '{}' {}; publishing as '{}'", old_name, why, alternative);
  avahi_free(alternative);
}

void ServicePublisher::handle_group(AvahiEntryGroup* group, int state) {
  switch (static_cast<AvahiEntryGroupState>(state)) {
    case AVAHI_ENTRY_GROUP_ESTABLISHED:
      log_->info("mDNS: published '{}' ({}, port {}, status {})", published_name(), spec_.type, spec_.port,
                 published_txt_["status"]);
      break;
    case AVAHI_ENTRY_GROUP_COLLISION:
      // Another host on the network probed the name first: the Avahi way is the next alternative name.
      take_alternative_name("is taken on the network");
      avahi_entry_group_reset(group);
      committed_ = false;
      add_and_commit();
      break;
    case AVAHI_ENTRY_GROUP_FAILURE:
      log_->error("mDNS: publishing '{}' failed: {}", published_name(), client_error(group));
      committed_ = false;
      break;
    case AVAHI_ENTRY_GROUP_UNCOMMITED:
    case AVAHI_ENTRY_GROUP_REGISTERING: break;
  }
}

void ServicePublisher::refresh_txt() {
  if (!connection_ || !connection_->running() || group_ == nullptr || !committed_ || !spec_.txt) return;
  auto txt = spec_.txt();
  if (txt == published_txt_) return;
  const TxtList list = to_txt_list(txt);
  const std::string name = published_name();
  const int updated = avahi_entry_group_update_service_txt_strlst(
      group_, AVAHI_IF_UNSPEC, AVAHI_PROTO_UNSPEC, AvahiPublishFlags(0), name.c_str(), spec_.type.c_str(), nullptr, list.get());
  if (updated < 0) {
    log_->warn("mDNS: cannot update the TXT record of '{}': {} (retrying)", name, avahi_strerror(updated));
    return;  // published_txt_ unchanged: the next tick tries again
  }
  log_->info("mDNS: '{}' TXT updated (status {})", name, txt["status"]);
  published_txt_ = std::move(txt);
}

void ServicePublisher::handle_tick(AvahiTimeout* timeout) {
  refresh_txt();
  timeval next{};
  avahi_elapse_time(&next, static_cast<unsigned>(spec_.refresh.count()), 0);
  connection_->poll_api()->timeout_update(timeout, &next);
}

void ServicePublisher::free_group() {
  if (group_ != nullptr) avahi_entry_group_free(group_);
  group_ = nullptr;
  committed_ = false;
}

}  // namespace rcand::mdns
