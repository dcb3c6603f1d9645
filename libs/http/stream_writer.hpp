// The SDK's StreamWriter (rcand/sdk/stream.hpp) on this server: a plugin's stream or binary answer becomes one
// Response (a body, a JSON answer, or the header of a ResponseStream whose parts it pushes). The multipart framing
// (boundary, each part's Content-Type and Content-Length) is done here, once per part, and the frame itself is shared.
#pragma once

#include <rcand/sdk/stream.hpp>

#include <functional>
#include <memory>
#include <string_view>

#include "libs/http/response.hpp"

namespace rcand::http {

// The boundary of every multipart stream this server sends.
inline constexpr std::string_view kStreamBoundary = "rcandframe";

// Delivers the writer's one answer; false when the request was answered already (its handler timed out), which the
// writer then reports as closed(). Called at most once, on the thread that answers.
using FirstAnswer = std::function<bool(Response)>;

// A writer dropped without an answer answers 500 INTERNAL; one dropped mid-stream ends the stream.
std::shared_ptr<sdk::StreamWriter> make_stream_writer(FirstAnswer answer);

}  // namespace rcand::http
