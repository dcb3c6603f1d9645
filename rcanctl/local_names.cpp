#include "local_names.hpp"

#include <future>
#include <stdexcept>
#include <vector>

#include "libs/base/logging.hpp"
#include "libs/mdns/host_resolver.hpp"

namespace rcand::rcanctl {

std::shared_ptr<HostResolver> local_name_resolver() {
  auto resolver = std::make_shared<mdns::AvahiHostResolver>(logger("rcanctl.mdns"));
  resolver->start();
  return resolver;
}

std::string address_of(const std::string& host, std::chrono::milliseconds timeout) {
  if (!mdns::is_mdns_host(host)) return host;
  mdns::AvahiHostResolver resolver(logger("rcanctl.mdns"), {.lookup_timeout = timeout});
  resolver.start();
  std::promise<std::pair<std::vector<std::string>, std::string>> answer;
  resolver.resolve(host, [&answer](std::vector<std::string> addresses, std::string why) {
    answer.set_value({std::move(addresses), std::move(why)});
  });
  auto [addresses, why] = answer.get_future().get();  // the resolver answers once, by its lookup timeout at the latest
  resolver.stop();
  if (addresses.empty()) throw std::runtime_error(host + ": " + why);
  return addresses.front();
}

}  // namespace rcand::rcanctl
