// The swarm's parallel HTTP client: one request per peer, all in flight at once on one event loop of its own
// (never the server's I/O threads), each bounded by the same deadline, so a dead, slow or refusing peer never
// delays the others. The deadline itself is kept by a second thread that does nothing else ("swarm.deadline",
// real-time when asked): however busy the I/O loop is with many broadcasts and hostile peers, each run answers at its
// deadline with the results that are in, the missing peers named as timed out (issue 28 #3). Hostnames resolve on a helper thread
// each (getaddrinfo cannot be cancelled and must not serialize peers), or through a HostResolver for the names it handles (mDNS
// "*.local"); when resolution fails or takes more than half the deadline the static `ip` fallback is used.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "libs/base/host_resolver.hpp"
#include "libs/http/tls_settings.hpp"
#include "libs/swarm/swarm_registry.hpp"

namespace rcand::swarm {

inline constexpr std::uint64_t kDefaultPeerBodyLimit = 1024 * 1024;
// What a stop answer may take: far above a real one (a few hundred bytes per driver).
inline constexpr std::uint64_t kStopAnswerLimit = 64 * 1024;

struct PeerRequest {
  std::string name;
  std::string host;                        // IP literal or hostname
  std::optional<std::string> fallback_ip;  // used when `host` does not resolve in time
  std::uint16_t port = 8000;
  std::string method = "GET";
  std::string target = "/";
  std::string body;
  std::vector<std::pair<std::string, std::string>> headers;  // e.g. Authorization (never logged)
  // A larger answer is that peer's failure: a stop's answer is small, and a peer streaming megabytes must not
  // make the fan-out thread (shared by every broadcast) late for everyone else's deadline.
  std::uint64_t body_limit = kDefaultPeerBodyLimit;
  // Set: HTTPS, the peer's certificate verified against tls->ca_file and `host` (a TLS failure is that peer's error;
  // nothing is sent to a peer that fails it). Contexts are kept per file set while the files stay unchanged.
  std::optional<http::ClientTlsSettings> tls;
};

// A request to a registry node: its name, host, ip fallback and port, authorized with the node's own token, over
// TLS when the node names a `ca`.
PeerRequest peer_request(const SwarmNode& node, std::string method, std::string target, std::string body = {});

struct PeerResult {
  std::string name;
  std::string address;     // "ip:port" contacted; empty when nothing could be resolved
  bool reachable = false;  // an HTTP answer arrived
  int status = 0;          // HTTP status when reachable
  std::string body;
  double latency_ms = 0;  // from the start of the fan-out to this peer's answer or failure
  std::string error;      // transport failure ("cannot connect to ...: Connection refused", "timed out after 300 ms")
};

class FanOut {
 public:
  using Done = std::function<void(std::vector<PeerResult>)>;

  // Starts the event-loop thread and the deadline thread. `resolver` (optional) resolves the hosts it handles instead
  // of getaddrinfo. `deadline_priority` > 0: the deadline thread is SCHED_FIFO at that priority (rcand passes
  // runtime.stop_path_priority: a broadcast stop's answer is on the stop path). `io_priority` > 0: the event-loop thread
  // too (rcand passes 1, below the stop path, so the peers' answers are read in time while the cores are saturated;
  // its work is bounded by the per-connection limits and the deadlines).
  explicit FanOut(std::shared_ptr<HostResolver> resolver = nullptr, int deadline_priority = 0, int io_priority = 0);
  ~FanOut();  // stop()
  FanOut(const FanOut&) = delete;
  FanOut& operator=(const FanOut&) = delete;

  // Sends every request in parallel; `done` runs once with the results in request order, when each one answered or
  // failed (on the fan-out thread), or at the deadline (on the deadline thread, every peer still pending failed with
  // "timed out after N ms"). The deadline is `timeout` from now (the whole exchange, resolution included), or
  // `answer_by` when that comes first (a broadcast stop's budget counts from its request). Thread-safe.
  // After stop(), pending and later runs never call `done`.
  void run(std::vector<PeerRequest> requests, std::chrono::milliseconds timeout, Done done,
           std::chrono::steady_clock::time_point answer_by = std::chrono::steady_clock::time_point::max());
  // run() and wait for the results (for rcanctl; never call it on the fan-out thread).
  std::vector<PeerResult> run_and_wait(std::vector<PeerRequest> requests, std::chrono::milliseconds timeout);
  // Abandons what is in flight and joins the thread. Idempotent.
  void stop() noexcept;

  struct Loop;

 private:
  std::shared_ptr<Loop> loop_;
};

}  // namespace rcand::swarm
