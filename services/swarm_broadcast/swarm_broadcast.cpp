#include "services/swarm_broadcast/swarm_broadcast.hpp"

#include <cctype>
#include <mutex>
#include <optional>

#include "kernel/api/answers.hpp"
#include "kernel/kernel.hpp"
#include "libs/base/json_body.hpp"
#include "libs/base/logging.hpp"
#include "libs/mdns/host_resolver.hpp"
#include "libs/swarm/broadcast_report.hpp"
#include "libs/swarm/fan_out.hpp"
#include "libs/swarm/node_selection.hpp"
#include "services/swarm_broadcast/swarm_metrics.hpp"
#include "services/swarm_broadcast/swarm_table.hpp"

namespace rcand::services {
namespace {

using kernel::Call;
using nlohmann::json;

using kernel::Reply;
using kernel::RouteHandler;

// Per-peer deadlines: a stop must finish inside 500 ms overall even with dead peers (§15.5); a command may take as
// long as a capability handler may.
constexpr std::chrono::milliseconds kStopPeerTimeout{300};
// A broadcast stop answers no later than this after its request reached the decorator, whatever the peers and however
// many broadcasts overlap: the peers get 300 ms after the local stop, less when the local stop itself was late (many
// stops queued on the accept thread). What is left of the 500 ms is for the request's wait before it was read and for
// the answer's write.
constexpr std::chrono::milliseconds kStopAnswerBudget{400};

bool header_true(const http::Request& request, std::string_view name) {
  const auto value = request.header(name);
  if (!value) return false;
  std::string lower(*value);
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return lower == "true" || lower == "1";
}

// "nodes"/"tags" of a broadcast body: a string or an array of strings.
std::optional<std::string> read_selection(const json& body, const char* key, std::vector<std::string>& out) {
  if (!body.is_object() || !body.contains(key) || body[key].is_null()) return std::nullopt;
  const json& value = body[key];
  if (value.is_string()) {
    out.push_back(value.get<std::string>());
    return std::nullopt;
  }
  if (!value.is_array()) return std::string(key) + " must be a string or an array of strings";
  for (const auto& item : value) {
    if (!item.is_string()) return std::string(key) + " must contain only strings";
    out.push_back(item.get<std::string>());
  }
  return std::nullopt;
}

// Both halves of a broadcast (the local run and the fan-out) report here; whichever finishes last answers.
struct Gather {
  std::mutex mutex;
  std::optional<json> local;
  std::optional<std::vector<swarm::PeerResult>> remote;
  json stop_fields;  // the local stop's own fields, kept on top of the report (null for a command)
};

class SwarmBroadcast final : public kernel::Service {
 public:
  SwarmBroadcast(kernel::ServiceHost& host, std::shared_ptr<swarm::LiveRegistry> swarm) : host_(host), swarm_(std::move(swarm)) {
    swarm_->replace(read_swarm_file(host.config.runtime.swarm_file, logger("kernel")));
    // docs/protocol.md §9: "mDNS host first, the static ip when resolution fails": *.local peers resolve through
    // avahi-daemon, prefetched so the first broadcast stop finds them in the cache.
    std::vector<std::string> mdns_hosts;
    for (const auto& node : swarm_->now().nodes)
      if (mdns::is_mdns_host(node.host)) mdns_hosts.push_back(node.host);
    if (!mdns_hosts.empty()) {
      resolver_ = std::make_shared<mdns::AvahiHostResolver>(logger("kernel.mdns"));
      resolver_->start();
      resolver_->prefetch(mdns_hosts);
    }
    // The deadline thread answers broadcast stops: real-time like the rest of the stop path. The peers' I/O is
    // real-time at the lowest priority, below every stop-path thread (issue 28 #3: at nice 0 on saturated cores it
    // fell behind and healthy peers' answers missed the deadline).
    const int stop_priority = host.config.runtime.stop_path_priority;
    fan_out_ = std::make_unique<swarm::FanOut>(resolver_, stop_priority, stop_priority > 1 ? 1 : 0);
    table_ = std::make_unique<SwarmTable>(host, *swarm_, *fan_out_);
  }
  ~SwarmBroadcast() override { stop(); }

  std::string_view name() const noexcept override { return "swarm_broadcast"; }

  void add_routes(kernel::Router& router) override {
    router.wrap("POST", "/api/stop",
                [this](Call& call, Reply reply, const RouteHandler& next) { stop_route(call, std::move(reply), next); });
    router.wrap("POST", "/api/command",
                [this](Call& call, Reply reply, const RouteHandler& next) { command_route(call, std::move(reply), next); });
    table_->add_routes(router);
  }

  // runtime.swarm_file is live: the file (this one or another) is read and checked, then swapped in whole.
  kernel::ServiceReload prepare_reload(const config::RobotConfig& next) override {
    auto peers = std::make_shared<swarm::SwarmRegistry>(read_swarm_file(next.runtime.swarm_file, nullptr));
    return {[swarm = swarm_, peers] { swarm->replace(std::move(*peers)); }, {"runtime.swarm_file"}};
  }

  void stop() noexcept override {
    if (fan_out_) fan_out_->stop();  // broadcasts in flight are abandoned; their clients are gone
    if (resolver_) resolver_->stop();
  }

 private:
  struct Broadcast {
    bool is_stop;
    json body;  // the request's body, an object (or empty)
    std::vector<swarm::SwarmNode> peers;
    std::chrono::steady_clock::time_point answer_by = std::chrono::steady_clock::time_point::max();
  };

  void stop_route(Call& call, Reply reply, const RouteHandler& next) {
    // The stop path: a stop that cannot be a broadcast (no header, no "broadcast" in its body) goes straight on,
    // without parsing its body here as well as in the stop handler.
    if (!header_true(call.request, "x-swarm-broadcast") && call.request.body.find("broadcast") == std::string::npos)
      return next(call, std::move(reply));
    JsonBody body = parse_json_body(call.request.body);
    const bool body_ok = body.error.empty() && body.value.is_object();
    if (call.request.header("x-swarm-forwarded") || !is_broadcast(call.request, body_ok, body.value))
      return next(call, std::move(reply));
    const auto answer_by = std::chrono::steady_clock::now() + kStopAnswerBudget;
    http::Response local;  // the local stop first, inline, before anything is forwarded
    next(call, [&local](http::Response response) { local = std::move(response); });
    broadcast({true, body_ok ? body.value : json::object(), {}, answer_by}, call, std::move(reply), std::move(local));
  }

  void command_route(Call& call, Reply reply, const RouteHandler& next) {
    if (call.request.header("x-swarm-forwarded")) {
      // Forwarded by a peer: it runs here only and is never forwarded again, unless this node is in e-stop.
      if (!host_.estop.latched()) return next(call, std::move(reply));
      const auto seq = host_.audit.begin(call.principal, call.message_id, "POST /api/command (swarm-forwarded)");
      host_.audit.finish(seq, "blocked", "e-stop active: acknowledged, not executed");
      reply(kernel::json_response(200, {{"ack", true}, {"executed", false}, {"reason", "estop_active"}}));
      return;
    }
    JsonBody body = parse_json_body(call.request.body);
    // Not a broadcast, or a body the normal path must refuse (400 naming the body).
    if (!body.error.empty() || !is_broadcast(call.request, body.value.is_object(), body.value))
      return next(call, std::move(reply));
    broadcast({false, body.value.is_object() ? body.value : json::object(), {}}, call, std::move(reply), {});
  }

  static bool is_broadcast(const http::Request& request, bool body_ok, const json& body) {
    return header_true(request, "x-swarm-broadcast") || (body_ok && body.contains("broadcast") && body["broadcast"] == true);
  }

  // The peers the body selects (all of them by default), this robot left out; or the 400 naming the field.
  std::optional<http::Response> select_peers(Broadcast& b) const {
    swarm::Selection selection;
    std::optional<std::string> bad = read_selection(b.body, "nodes", selection.names);
    std::string field = "nodes";
    if (!bad && (bad = read_selection(b.body, "tags", selection.tags))) field = "tags";
    const swarm::SwarmRegistry& registry = swarm_->now();
    if (!bad) {
      auto chosen = swarm::select_nodes(registry, selection);
      if (auto* failure = std::get_if<swarm::SelectionError>(&chosen)) {
        bad = failure->message;
        field = failure->field;
      } else {
        for (auto& node : std::get<std::vector<swarm::SwarmNode>>(chosen))
          if (!is_this_robot(node, host_)) b.peers.push_back(std::move(node));
      }
    }
    if (!bad) return std::nullopt;
    json extra{{"field", field}, {"known_nodes", registry.names()}};
    if (b.is_stop) extra["estopped"] = true;  // the local stop already happened
    return kernel::error_response(400, "BAD_REQUEST", *bad, std::move(extra));
  }

  // What the peers receive: the same command minus the broadcast fields, with their own token.
  std::vector<swarm::PeerRequest> peer_requests(const Broadcast& b, const Call& call, json& forwarded_body) const {
    const std::string& ruri = host_.registry.identity().ruri;
    forwarded_body = b.body;
    for (const char* key : {"broadcast", "nodes", "tags"}) forwarded_body.erase(key);
    if (b.is_stop && !forwarded_body.contains("reason")) forwarded_body["reason"] = "swarm broadcast from " + ruri;
    std::vector<swarm::PeerRequest> requests;
    for (const auto& node : b.peers) {
      auto peer = swarm::peer_request(node, "POST", call.request.path, forwarded_body.dump());
      if (b.is_stop) peer.body_limit = swarm::kStopAnswerLimit;
      peer.headers.emplace_back("X-Swarm-Forwarded", ruri);
      peer.headers.emplace_back("X-Message-Id", call.message_id);
      requests.push_back(std::move(peer));
    }
    return requests;
  }

  void broadcast(Broadcast b, Call& call, Reply reply, http::Response local_stop) {
    if (auto refusal = select_peers(b)) return reply(std::move(*refusal));
    json forwarded_body;
    auto requests = peer_requests(b, call, forwarded_body);
    const auto seq = host_.audit.begin(call.principal, call.message_id, "swarm broadcast POST " + call.request.path, nullptr,
                                       b.is_stop ? kernel::AuditRetention::Stop : kernel::AuditRetention::Record);
    auto gather = std::make_shared<Gather>();
    auto complete = [audit = &host_.audit, directory = &host_.plugin_services, gather, seq, reply = std::move(reply)] {
      answer(*audit, *directory, *gather, seq, reply);
    };
    if (b.is_stop) {
      gather->stop_fields = json::parse(local_stop.body, nullptr, false);
      if (!gather->stop_fields.is_object()) gather->stop_fields = json::object();
      gather->local = local_stop_entry(gather->stop_fields, local_stop.status);
    } else {
      run_local_command(call, forwarded_body, gather, complete);
    }
    auto remote_done = [gather, complete](std::vector<swarm::PeerResult> results) {
      {
        std::lock_guard lock(gather->mutex);
        gather->remote = std::move(results);
      }
      complete();
    };
    const auto timeout = b.is_stop ? kStopPeerTimeout : host_.handler_timeout + std::chrono::milliseconds(2000);
    if (!requests.empty()) fan_out_->run(std::move(requests), timeout, std::move(remote_done), b.answer_by);
    else remote_done({});
  }

  json local_stop_entry(const json& stop, int http_status) const {
    const bool stopped = is_true(stop, "motors_stopped");
    return {{"name", host_.registry.identity().name},
            {"address", "local"},
            {"local", true},
            {"ok", stopped},
            {"http_status", http_status},
            {"executed", true},
            {"motors_stopped", stopped},
            {"latency_ms", stop.value("latency_us", 0.0) / 1000.0},
            {"error", stopped ? json() : json("not every driver confirmed the halt")}};
  }

  // The local run goes through the normal path, marked as forwarded so it is not broadcast again and the e-stop
  // acknowledgement applies here too.
  void run_local_command(const Call& call, const json& body, const std::shared_ptr<Gather>& gather,
                         std::function<void()> complete) {
    http::Request local = call.request;
    local.headers.erase("x-swarm-broadcast");
    local.headers["x-swarm-forwarded"] = host_.registry.identity().ruri;
    local.headers["x-message-id"] = call.message_id;
    local.body = body.dump();
    const auto started = std::chrono::steady_clock::now();
    host_.api.handle(
        std::move(local), [gather, complete, name = host_.registry.identity().name, started](http::Response response) {
          swarm::PeerResult result;
          result.name = name;
          result.address = "local";
          result.reachable = true;
          result.status = response.status;
          result.body = std::move(response.body);
          result.latency_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - started).count();
          json entry = swarm::node_entry(result, swarm::BroadcastKind::Command);
          entry["local"] = true;
          {
            std::lock_guard lock(gather->mutex);
            gather->local = std::move(entry);
          }
          complete();
        });
  }

  static void answer(kernel::AuditLog& audit, const kernel::ServiceDirectory& directory, Gather& gather, std::uint64_t seq,
                     const Reply& reply) {
    json local;
    std::vector<swarm::PeerResult> remote;
    {
      std::lock_guard lock(gather.mutex);
      if (!gather.local || !gather.remote) return;
      local = std::move(*gather.local);
      remote = std::move(*gather.remote);
      gather.remote.reset();
      gather.local.reset();
    }
    const bool is_stop = gather.stop_fields.is_object();
    std::vector<json> nodes{std::move(local)};
    for (const auto& result : remote)
      nodes.push_back(swarm::node_entry(result, is_stop ? swarm::BroadcastKind::Stop : swarm::BroadcastKind::Command));
    json doc = swarm::broadcast_document(std::move(nodes));
    record_broadcast(directory, is_stop ? "stop" : "command", doc["nodes"]);
    const auto& summary = doc["summary"];
    audit.finish(seq, summary["failed"] == 0 ? "ok" : "error",
                 summary["ok"].dump() + "/" + summary["total"].dump() + " nodes ok");
    if (is_stop) doc.update(gather.stop_fields);  // the local stop's own fields stay on top
    reply(kernel::json_response(200, doc));
  }

  kernel::ServiceHost& host_;
  std::shared_ptr<swarm::LiveRegistry> swarm_;         // loaded and reloaded here; R2R reads it too
  std::shared_ptr<mdns::AvahiHostResolver> resolver_;  // swarm "*.local" hosts; shared with the fan-out
  std::unique_ptr<swarm::FanOut> fan_out_;
  std::unique_ptr<SwarmTable> table_;  // GET /api/swarm, POST /api/swarm/<node>/stop, on the same fan-out
};

}  // namespace

swarm::SwarmRegistry read_swarm_file(const std::filesystem::path& file, const std::shared_ptr<spdlog::logger>& log) {
  if (std::error_code ec; !std::filesystem::exists(file, ec)) {
    if (log) log->info("swarm: no swarm file at {}; broadcasts reach this robot only", file.string());
    return {};
  }
  swarm::SwarmRegistry registry;
  try {
    registry = swarm::load_swarm_file(file);
  } catch (const swarm::SwarmError& e) {
    throw kernel::StartupError(std::string("runtime.swarm_file: ") + e.what());
  }
  if (log) {
    for (const auto& warning : registry.warnings) log->warn("{}", warning);
    log->info("swarm: {} peer(s) from {}", registry.nodes.size(), file.string());
  }
  return registry;
}

void check_swarm_file(const config::RobotConfig& config) { read_swarm_file(config.runtime.swarm_file, nullptr); }

std::unique_ptr<kernel::Service> make_swarm_broadcast(kernel::ServiceHost& host, std::shared_ptr<swarm::LiveRegistry> swarm) {
  return std::make_unique<SwarmBroadcast>(host, std::move(swarm));
}

}  // namespace rcand::services
