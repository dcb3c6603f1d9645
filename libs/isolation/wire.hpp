// The SDK's values as messages on an isolated capability's channel (channel.hpp): a route without its handler, a
// request (without its credential, which never leaves rcand), a response. Both ends are built from one tree, so the
// encoding is positional and unversioned; a field that does not decode throws nlohmann::json's exception.
#pragma once

#include <nlohmann/json.hpp>

#include "rcand/sdk/capability.hpp"
#include "rcand/sdk/http.hpp"
#include "rcand/sdk/stream.hpp"

namespace rcand::isolation {

nlohmann::json encode_route(const sdk::Route& route);
sdk::Route decode_route(const nlohmann::json& message);  // no handler: the caller gives it one

nlohmann::json encode_stream_route(const sdk::StreamRoute& route);
sdk::StreamRoute decode_stream_route(const nlohmann::json& message);  // no handler

nlohmann::json encode_request(const sdk::Request& request);
sdk::Request decode_request(const nlohmann::json& message);

}  // namespace rcand::isolation
