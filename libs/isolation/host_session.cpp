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
#include "libs/isolation/wire.hpp"

namespace rcand::isolation {

using nlohmann::json;

namespace {

// The capability made and started as rcand would, its routes checked for what the host itself needs.
std::unique_ptr<sdk::Capability> start_capability(const LoadedCapability& loaded, HostContext& context,
                                                  std::vector<sdk::Route>& routes) {
  auto object = loaded.factory(context);
  if (!object) throw std::runtime_error("its factory returned no capability");
  object->start();
  routes = object->routes();
  for (const auto& route : routes)
    if (!route.handler)
      throw std::runtime_error("routes() returned a route without a handler: " + route.method + " " + route.path);
  if (loaded.abi_minor >= 2 && !object->stream_routes().empty())
    throw std::runtime_error("it serves stream routes, which isolation: process does not carry yet; run it in_process");
  return object;
}

// A handler's answer, or what it threw ("threw": rcand throws it again on its side, where a throw is answered, logged
// and counted as in process: docs/protocol.md §7.16).
void answer(Channel& channel, const std::vector<sdk::Route>& routes, const json& message) {
  sdk::Response response;
  try {
    response = routes.at(message.at("route").get<std::size_t>()).handler(decode_request(message.at("req")));
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

int run_host(Channel& channel, const CapabilityLoader& load) {
  const auto start = channel.receive();
  if (!start || start->value("t", "") != "start") return 2;
  HostContext context(channel, *start);
  std::vector<sdk::Route> routes;
  std::atomic<sdk::Capability*> served{nullptr};  // set once it started, its routes complete
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
      sdk::Capability* object = served.load();
      if (type == "reply") {
        context.deliver(*message);
      } else if (type == "ping") {
        context.set_latched(message->value("latched", false));
        channel.send({{"t", "pong"}});
      } else if (type == "estop") {
        context.set_latched(true);
        if (object != nullptr) stops.post([object] { object->on_estop(); });
      } else if (type == "request" && object != nullptr) {  // rcand sends none before it started
        requests.post([&channel, &routes, message = *message] { answer(channel, routes, message); });
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
    std::lock_guard lock(mutex);
    ended = true;
    changed.notify_all();
  });

  LoadedCapability loaded;
  std::unique_ptr<sdk::Capability> object;
  try {
    loaded = load(*start);
    object = start_capability(loaded, context, routes);
  } catch (const std::exception& e) {
    channel.send({{"t", "start_failed"}, {"reason", e.what()}});
    channel.shutdown();
    reader.join();
    return 3;
  }
  json specs = json::array();
  for (const auto& route : routes) specs.push_back(encode_route(route));
  served.store(object.get());
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
