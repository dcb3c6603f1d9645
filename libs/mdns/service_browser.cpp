#include "libs/mdns/service_browser.hpp"

#include <avahi-client/client.h>
#include <avahi-client/lookup.h>
#include <avahi-common/address.h>
#include <avahi-common/error.h>
#include <avahi-common/simple-watch.h>

#include <algorithm>
#include <memory>

#include "libs/mdns/txt_list.hpp"

namespace rcand::mdns {
namespace {

struct Browse {
  AvahiClient* client = nullptr;
  std::map<std::string, DiscoveredService> found;  // by instance name: one entry per robot, whatever the interface
  int resolving = 0;
  bool all_for_now = false;
  std::string error;
};

void on_resolved(AvahiServiceResolver* resolver, AvahiIfIndex, AvahiProtocol, AvahiResolverEvent event, const char* name,
                 const char*, const char*, const char* host, const AvahiAddress* address, std::uint16_t port,
                 AvahiStringList* txt, AvahiLookupResultFlags, void* userdata) {
  auto* browse = static_cast<Browse*>(userdata);
  --browse->resolving;
  if (event == AVAHI_RESOLVER_FOUND && name != nullptr && address != nullptr) {
    DiscoveredService service;
    service.name = name;
    service.host = host != nullptr ? host : "";
    char text[AVAHI_ADDRESS_STR_MAX];
    avahi_address_snprint(text, sizeof text, address);
    service.address = text;
    service.port = port;
    service.txt = from_txt_list(txt);
    browse->found[service.name] = std::move(service);
  }
  avahi_service_resolver_free(resolver);
}

void on_browse(AvahiServiceBrowser*, AvahiIfIndex interface, AvahiProtocol protocol, AvahiBrowserEvent event, const char* name,
               const char* type, const char* domain, AvahiLookupResultFlags, void* userdata) {
  auto* browse = static_cast<Browse*>(userdata);
  switch (event) {
    case AVAHI_BROWSER_NEW:
      if (avahi_service_resolver_new(browse->client, interface, protocol, name, type, domain, AVAHI_PROTO_INET,
                                     AvahiLookupFlags(0), &on_resolved, browse) != nullptr)
        ++browse->resolving;
      break;
    case AVAHI_BROWSER_REMOVE: browse->found.erase(name); break;
    case AVAHI_BROWSER_ALL_FOR_NOW: browse->all_for_now = true; break;
    case AVAHI_BROWSER_FAILURE:
      browse->error = std::string("browsing failed: ") + avahi_strerror(avahi_client_errno(browse->client));
      break;
    case AVAHI_BROWSER_CACHE_EXHAUSTED: break;
  }
}

struct PollFree {
  void operator()(AvahiSimplePoll* poll) const noexcept { avahi_simple_poll_free(poll); }
};
struct ClientFree {
  void operator()(AvahiClient* client) const noexcept { avahi_client_free(client); }
};

}  // namespace

BrowseOutcome browse_services(const std::string& type, std::chrono::milliseconds timeout) {
  BrowseOutcome outcome;
  std::unique_ptr<AvahiSimplePoll, PollFree> poll(avahi_simple_poll_new());
  if (!poll) {
    outcome.error = "cannot create an Avahi event loop";
    return outcome;
  }
  Browse browse;
  int error = 0;
  // No NO_FAIL: a one-shot browse without avahi-daemon is an error to report, not something to wait for.
  std::unique_ptr<AvahiClient, ClientFree> client(
      avahi_client_new(avahi_simple_poll_get(poll.get()), AvahiClientFlags(0), nullptr, nullptr, &error));
  if (!client) {
    outcome.error = std::string("cannot reach avahi-daemon: ") + avahi_strerror(error);
    return outcome;
  }
  browse.client = client.get();
  // IPv4 only, so each robot is listed once per interface at most (and an address is directly usable).
  if (avahi_service_browser_new(client.get(), AVAHI_IF_UNSPEC, AVAHI_PROTO_INET, type.c_str(), nullptr, AvahiLookupFlags(0),
                                &on_browse, &browse) == nullptr) {
    outcome.error = std::string("cannot browse ") + type + ": " + avahi_strerror(avahi_client_errno(client.get()));
    return outcome;
  }
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (browse.error.empty() && !(browse.all_for_now && browse.resolving == 0)) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) break;
    if (avahi_simple_poll_iterate(poll.get(), static_cast<int>(left.count())) != 0) break;
  }
  outcome.error = browse.error;
  for (auto& [name, service] : browse.found) outcome.services.push_back(std::move(service));
  return outcome;  // the client (and its browser and resolvers) is freed before the poll
}

}  // namespace rcand::mdns
