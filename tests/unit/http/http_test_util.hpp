// Shared helpers for the http tests: an echo handler and a started server on 127.0.0.1, port 0.
#pragma once

#include <nlohmann/json.hpp>

#include <memory>
#include <utility>

#include "libs/http/server.hpp"

namespace rcand::test {

namespace http = rcand::http;

// Answers with the request as JSON, so tests can see what the server decoded.
inline http::Response echo_response(const http::Request& request) {
  nlohmann::json body = {{"method", request.method}, {"target", request.target}, {"path", request.path},
                         {"query", request.query},   {"headers", request.headers}, {"body", request.body},
                         {"remote", request.remote}};
  http::Response response;
  response.body = body.dump();
  return response;
}

inline http::Handler echo_handler() {
  return [](http::Request&& request, http::Respond respond) { respond(echo_response(request)); };
}

struct StartedServer {
  std::unique_ptr<http::Server> server;
  std::uint16_t port = 0;

  explicit StartedServer(http::Handler handler, http::ServerOptions options = {}) {
    options.address = "127.0.0.1";
    options.port = 0;
    server = std::make_unique<http::Server>(std::move(options), std::move(handler));
    port = server->start();
  }
};

}  // namespace rcand::test
