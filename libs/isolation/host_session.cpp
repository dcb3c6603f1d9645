#include "libs/isolation/host_session.hpp"

#include <stdexcept>
#include <string>
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

void answer(Channel& channel, const std::vector<sdk::Route>& routes, const json& message) {
  sdk::Response response;
  try {
    response = routes.at(message.at("route").get<std::size_t>()).handler(decode_request(message.at("req")));
  } catch (const std::exception& e) {
    response = sdk::Response::error(500, "INTERNAL", std::string("the capability's handler failed: ") + e.what());
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
  LoadedCapability loaded;
  std::unique_ptr<sdk::Capability> object;
  std::vector<sdk::Route> routes;
  try {
    loaded = load(*start);
    object = start_capability(loaded, context, routes);
  } catch (const std::exception& e) {
    channel.send({{"t", "start_failed"}, {"reason", e.what()}});
    return 3;
  }
  json specs = json::array();
  for (const auto& route : routes) specs.push_back(encode_route(route));
  channel.send({{"t", "started"}, {"routes", specs}});

  const auto ignore = [](const std::string&) {};
  WorkerThread requests("cap." + std::string(context.instance_id()), ignore), stops("estop", ignore), statuses("status", ignore);
  while (const auto message = channel.receive()) {
    const std::string type = message->value("t", "");
    if (type == "request") {
      requests.post([&channel, &routes, message = *message] { answer(channel, routes, message); });
    } else if (type == "ping") {
      context.set_latched(message->value("latched", false));
      channel.send({{"t", "pong"}});
    } else if (type == "estop") {
      context.set_latched(true);
      stops.post([&object] { object->on_estop(); });
    } else if (type == "status?") {
      statuses.post([&channel, &object, id = message->at("id")] {
        json status;
        try {
          status = object->status();
        } catch (const std::exception& e) {
          status = {{"fault", std::string("status() threw: ") + e.what()}};
        }
        channel.send({{"t", "status"}, {"id", id}, {"status", status}});
      });
    } else if (type == "reply") {
      context.deliver(*message);
    } else if (type == "shutdown") {
      break;
    }
  }
  context.close();
  object->shutdown();
  requests.join();
  stops.join();
  statuses.join();
  context.join_workers();
  return 0;
}

}  // namespace rcand::isolation
