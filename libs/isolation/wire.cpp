#include "libs/isolation/wire.hpp"

namespace rcand::isolation {

nlohmann::json encode_route(const sdk::Route& route) {
  return {route.method, route.path, static_cast<int>(route.scope), route.motion, route.action_type};
}

sdk::Route decode_route(const nlohmann::json& message) {
  sdk::Route route;
  route.method = message.at(0).get<std::string>();
  route.path = message.at(1).get<std::string>();
  route.scope = static_cast<sdk::Scope>(message.at(2).get<int>());
  route.motion = message.at(3).get<bool>();
  route.action_type = message.at(4).get<std::string>();
  return route;
}

nlohmann::json encode_stream_route(const sdk::StreamRoute& route) {
  return {route.method, route.path, static_cast<int>(route.scope)};
}

sdk::StreamRoute decode_stream_route(const nlohmann::json& message) {
  sdk::StreamRoute route;
  route.method = message.at(0).get<std::string>();
  route.path = message.at(1).get<std::string>();
  route.scope = static_cast<sdk::Scope>(message.at(2).get<int>());
  return route;
}

nlohmann::json encode_request(const sdk::Request& request) {
  nlohmann::json scopes = nlohmann::json::array();
  for (const auto scope : request.scopes) scopes.push_back(static_cast<int>(scope));
  return {request.method,
          request.path,
          request.subpath,
          request.query,
          request.body,
          request.principal,
          static_cast<int>(request.role),
          request.message_id,
          scopes};
}

sdk::Request decode_request(const nlohmann::json& message) {
  sdk::Request request;
  request.method = message.at(0).get<std::string>();
  request.path = message.at(1).get<std::string>();
  request.subpath = message.at(2).get<std::string>();
  request.query = message.at(3).get<std::map<std::string, std::string>>();
  request.body = message.at(4);
  request.principal = message.at(5).get<std::string>();
  request.role = static_cast<sdk::Role>(message.at(6).get<int>());
  request.message_id = message.at(7).get<std::string>();
  for (const auto& scope : message.at(8)) request.scopes.push_back(static_cast<sdk::Scope>(scope.get<int>()));
  return request;
}

}  // namespace rcand::isolation
