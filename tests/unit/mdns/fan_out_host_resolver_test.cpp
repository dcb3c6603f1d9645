// The fan-out hands the hosts a HostResolver handles to it (mDNS "*.local" in rcand), and keeps getaddrinfo and
// the ip fallback for the rest; a resolver that never answers costs half the deadline, then the fallback.
#include <doctest/doctest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <thread>

#include "libs/http/server.hpp"
#include "libs/swarm/fan_out.hpp"

using namespace rcand;
using namespace std::chrono_literals;

namespace {

// Knows "known.local" (answering from a thread of its own, as avahi's does), fails "absent.local", and never
// answers "silent.local".
class FakeResolver final : public HostResolver {
 public:
  bool handles(std::string_view host) const override { return host.ends_with(".local"); }
  void resolve(const std::string& host, Done done) override {
    ++calls;
    if (host == "silent.local") {
      std::lock_guard lock(mutex);
      parked.push_back(std::move(done));  // answered only at destruction
      return;
    }
    std::thread([host, done = std::move(done)] {
      if (host == "known.local") done({"127.0.0.1"}, {});
      else done({}, "not found through mDNS");
    }).detach();
  }
  ~FakeResolver() override {
    for (auto& done : parked) done({}, "gone");
  }
  std::atomic<int> calls{0};
  std::mutex mutex;
  std::vector<Done> parked;
};

struct Peer {
  std::unique_ptr<http::Server> server;
  std::uint16_t port = 0;
  Peer() {
    http::ServerOptions options;
    options.address = "127.0.0.1";
    options.port = 0;
    server = std::make_unique<http::Server>(options, [](http::Request&&, http::Respond respond) {
      http::Response response;
      response.body = "{}";
      respond(std::move(response));
    });
    port = server->start();
  }
};

swarm::PeerRequest to(const std::string& host, std::uint16_t port, std::optional<std::string> fallback = std::nullopt) {
  swarm::PeerRequest request;
  request.name = host;
  request.host = host;
  request.port = port;
  request.fallback_ip = std::move(fallback);
  request.target = "/health";
  return request;
}

}  // namespace

TEST_CASE("*.local peers resolve through the HostResolver; its failures and silences fall back to the static ip") {
  Peer peer;
  auto resolver = std::make_shared<FakeResolver>();
  swarm::FanOut fan_out(resolver);
  const auto started = std::chrono::steady_clock::now();
  auto results = fan_out.run_and_wait({to("known.local", peer.port), to("absent.local", peer.port, "127.0.0.1"),
                                       to("silent.local", peer.port, "127.0.0.1"), to("absent.local", peer.port),
                                       to("localhost", peer.port)},
                                      400ms);
  const auto took = std::chrono::steady_clock::now() - started;
  const std::string at = "127.0.0.1:" + std::to_string(peer.port);
  CHECK(results[0].status == 200);  // getaddrinfo does not know known.local: only the resolver could
  CHECK(results[0].address == at);
  CHECK(results[1].status == 200);  // the ip fallback
  CHECK(results[2].status == 200);  // the fallback after half the deadline
  CHECK_FALSE(results[3].reachable);
  CHECK(results[3].error == "cannot resolve host 'absent.local': not found through mDNS (and no ip fallback)");
  CHECK(results[4].status == 200);  // not the resolver's: getaddrinfo
  CHECK(resolver->calls == 4);
  CHECK(took < 400ms);  // generous: the silent one waits 200 ms, then connects on loopback
  fan_out.stop();
}
