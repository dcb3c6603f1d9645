#include "libs/isolation/host_session.hpp"

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "libs/base/worker_thread.hpp"
#include "libs/isolation/host_context.hpp"
#include "libs/isolation/remote_stream.hpp"
#include "libs/isolation/wire.hpp"

namespace rcand::isolation {

using nlohmann::json;

namespace {

struct Served {
  std::vector<sdk::Route> routes;
  std::vector<sdk::StreamRoute> streams;
};

// The capability made and started as rcand would, its routes checked for what the host itself needs.
std::unique_ptr<sdk::Capability> start_capability(const LoadedCapability& loaded, HostContext& context, Served& served) {
  auto object = loaded.factory(context);
  if (!object) throw std::runtime_error("its factory returned no capability");
  object->start();
  served.routes = object->routes();
  if (loaded.abi_minor >= 2) served.streams = object->stream_routes();  // older plugins have no such virtual
  for (const auto& route : served.routes)
    if (!route.handler)
      throw std::runtime_error("routes() returned a route without a handler: " + route.method + " " + route.path);
  for (const auto& route : served.streams)
    if (!route.handler)
      throw std::runtime_error("stream_routes() returned a route without a handler: " + route.method + " " + route.path);
  return object;
}

// A handler's answer (a stream handler's: that it returned, status 0), or what it threw ("threw": rcand throws it
// again on its side, where a throw is answered, logged and counted as in process: docs/protocol.md §7.16).
void answer(Channel& channel, const Served& served, RemoteStreams& streams, HostContext& context, const json& message) {
  sdk::Response response{0, nullptr};
  try {
    const auto route = message.at("route").get<std::size_t>();
    sdk::Request request = decode_request(message.at("req"));
    request.credential = context.dispatcher().credential(message.value("cred", json()));
    if (message.at("t") == "stream")
      served.streams.at(route).handler(request, streams.open(message.at("v").get<std::uint64_t>()));
    else response = served.routes.at(route).handler(request);
  } catch (const std::exception& e) {
    channel.send({{"t", "response"}, {"id", message.at("id")}, {"threw", e.what()}});
    return;
  } catch (...) {
    channel.send({{"t", "response"}, {"id", message.at("id")}, {"threw", "a non-standard exception"}});
    return;
  }
  std::string error;
  if (!channel.send({{"t", "response"}, {"id", message.at("id")}, {"status", response.status}, {"body", response.body}}, &error))
    channel.send({{"t", "response"},
                  {"id", message.at("id")},
                  {"status", 500},
                  {"body", sdk::Response::error(500, "INTERNAL", "the capability's answer cannot be sent: " + error).body}});
}

}  // namespace

int run_host(Channel& channel, FrameRing* ring, const CapabilityLoader& load, const SandboxEntry& sandbox) {
  const auto start = channel.receive();
  if (!start || start->value("t", "") != "start") return 2;
  if (sandbox) {
    try {
      channel.send({{"t", "sandbox"}, {"sandbox", sandbox(*start)}});  // before any status its start() publishes
    } catch (const std::exception& e) {
      channel.send({{"t", "start_failed"}, {"reason", e.what()}});
      return 3;
    }
  }
  HostContext context(channel, *start);
  Served served;
  RemoteStreams streams(channel, ring);
  std::atomic<sdk::Capability*> serving{nullptr};  // set once it started, its routes complete
  const auto ignore = [](const std::string&) {};
  WorkerThread requests("cap." + std::string(context.instance_id()), ignore), stops("estop", ignore), statuses("status", ignore);
  std::mutex mutex;
  std::condition_variable changed;
  bool ended = false;  // rcand said shutdown, or the channel ended
  // The reader runs from the start: a capability that moves, reads an actuator or asks for a stop in its start() waits
  // for rcand's answer, which only the reader can take.
  std::thread reader([&] {
    while (const auto message = channel.receive()) {
      const std::string type = message->value("t", "");
      sdk::Capability* object = serving.load();
      if (type == "reply") {
        context.deliver(*message);
      } else if (type == "ping") {
        context.set_latched(message->value("latched", false));
        context.pose().update(*message);
        channel.send({{"t", "pong"}});
      } else if (type == "estop") {
        context.set_latched(true);
        if (object != nullptr) stops.post([object] { object->on_estop(); });
      } else if ((type == "request" || type == "stream") && object != nullptr) {  // rcand sends none before it started
        context.pose().update(*message);
        if (const auto latched = message->find("latched"); latched != message->end()) context.set_latched(latched->get<bool>());
        requests.post([&, message = *message] { answer(channel, served, streams, context, message); });
      } else if (type == "s_state") {
        streams.update(*message);
      } else if (type == "s_started") {
        streams.started(*message);
      } else if (type == "dispatched") {
        context.dispatcher().answered(*message);
      } else if (type == "status?" && object != nullptr) {
        statuses.post([&channel, object, id = message->at("id")] {
          json status;
          try {
            status = object->status();
          } catch (const std::exception& e) {
            status = {{"fault", std::string("status() threw: ") + e.what()}};
          }
          channel.send({{"t", "status"}, {"id", id}, {"status", status}});
        });
      } else if (type == "shutdown") {
        break;
      }
    }
    context.close();  // calls still waiting on rcand return
    streams.close_all();
    std::lock_guard lock(mutex);
    ended = true;
    changed.notify_all();
  });

  LoadedCapability loaded;
  std::unique_ptr<sdk::Capability> object;
  try {
    loaded = load(*start);
    object = start_capability(loaded, context, served);
  } catch (const std::exception& e) {
    channel.send({{"t", "start_failed"}, {"reason", e.what()}});
    channel.shutdown();
    reader.join();
    return 3;
  }
  json specs{{"routes", json::array()}, {"streams", json::array()}};
  for (const auto& route : served.routes) specs["routes"].push_back(encode_route(route));
  for (const auto& route : served.streams) specs["streams"].push_back(encode_stream_route(route));
  serving.store(object.get());
  channel.send({{"t", "started"}, {"routes", specs}});
  {
    std::unique_lock lock(mutex);
    changed.wait(lock, [&] { return ended; });
  }
  object->shutdown();
  requests.join();
  stops.join();
  statuses.join();
  context.join_workers();
  reader.join();
  return 0;
}

}  // namespace rcand::isolation
