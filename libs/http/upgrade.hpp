// The connection the HTTP server hands over when a ServerOptions::upgrade hook takes a WebSocket upgrade request:
// the Beast stream (already past the request), the raw request (Beast's websocket accept needs it) and the bytes
// read after it. Only the code that takes connections includes this (it pulls in Beast).
#pragma once

#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/http/message.hpp>
#include <boost/beast/http/string_body.hpp>

#include <string>

#include "libs/http/connection_stream.hpp"
#include "libs/http/request.hpp"
#include "libs/http/server_options.hpp"

namespace rcand::http {

// The server's stream type: plain TCP, or TLS (already past its handshake) on a runtime.listen.tls address. Its
// executor is the I/O thread's event loop (single-threaded: no strand needed there); get_lowest_layer() of a
// websocket::stream over it is the TCP stream either way.
using UpgradeStream = ConnectionStream;

struct Upgraded {
  UpgradeStream stream;  // still carries the request deadline: call expires_never() before using it
  boost::beast::http::request<boost::beast::http::string_body> raw;
  boost::beast::flat_buffer buffer;  // bytes the client sent after the request (may be its first frames)
  Request request;                   // as the hook saw it
};

}  // namespace rcand::http
