// Binary and streaming answers (SDK ABI 1.2): a snapshot JPEG, or a multipart stream that runs for as long as the
// client watches (GET /api/stream/mjpeg). sdk::Route answers with one JSON Response; a StreamRoute instead gets a
// StreamWriter that it may keep and write to from any thread after the handler returned.
//
// Capability::stream_routes() returns them. The kernel mounts them in its one route table, so authentication (a
// bearer token, or ?token= on GET /api/stream/mjpeg as docs/protocol.md §3 allows), scopes, rate limits, the audit
// log and the 404/503 answers of an undeclared or failed capability apply exactly as to other routes. It calls
// stream_routes() only for plugins built for ABI 1.2 or later: older ones have no such virtual.
//
// Multipart streams hold AT MOST ONE pending part per client. push() never waits for the client: a part pushed while
// the previous one is still unsent replaces it, and the replaced part counts as dropped. A slow client therefore skips
// frames, holds one frame in memory, and never slows the producer or another client. A client that stops reading
// altogether is disconnected after a while (10 s without progress in rcand), and so is a stream offered no part for
// that long (its connection ends cleanly after the last whole part); closed() then turns true. rcand also caps the
// multipart streams one principal below OWNER, and one client address, may hold at once: a start() beyond them
// returns false and the client gets 429 TOO_MANY_STREAMS.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "rcand/sdk/export.hpp"
#include "rcand/sdk/http.hpp"
#include "rcand/sdk/scope.hpp"

namespace rcand::sdk {

// Extra response or part headers. Names and values with CR, LF or NUL are dropped; Content-Length,
// Transfer-Encoding, Connection and Server are the host's.
using Headers = std::vector<std::pair<std::string, std::string>>;

// Bytes shared by reference: one encoded frame is pushed to every client without a copy per client.
using SharedBytes = std::shared_ptr<const std::string>;

// One part of a multipart stream: the host writes the boundary, Content-Type, Content-Length and `headers`, then
// `data`.
struct StreamPart {
  SharedBytes data;
  std::string content_type = "image/jpeg";
  Headers headers;  // e.g. {"X-Timestamp-Us", "..."}: when the frame was captured
};

// Per client. `sent` counts parts (or the one body) written to the socket whole.
struct StreamCounters {
  std::uint64_t sent = 0;
  std::uint64_t dropped = 0;  // parts replaced before they were sent: the client read slower than the stream
  std::uint64_t bytes = 0;    // body bytes written
};

// Implemented by the host (the kernel, or testing/recording_stream.hpp). Every method: any thread, never blocks,
// never throws. Exactly one of three answers, once:
//   respond(json)                         a JSON answer (errors get the {"error","code","status"} shape)
//   start(status, type) then send(body)   one whole body, e.g. a snapshot: start(200, "image/jpeg"), send(jpeg)
//   start(200, "multipart/x-mixed-replace") then push(part)... and end() (or until the client leaves)
// A writer dropped without an answer answers 500; one dropped mid-stream ends the stream.
class RCAND_INTERFACE StreamWriter {
 public:
  virtual ~StreamWriter() = default;
  // Starts the answer. For a "multipart/..." content type (no parameters) the host adds the boundary and frames
  // each push(); for any other type send() follows. false: already answered, or the client is gone.
  virtual bool start(int status, std::string content_type, Headers headers = {}) noexcept = 0;
  // After start() with a non-multipart type: the whole body; the answer is then complete.
  virtual bool send(SharedBytes body) noexcept = 0;
  // Instead of start(): a JSON answer with extra headers (a 503 with Retry-After, say). Completes the answer.
  virtual bool respond(const Response& response, Headers headers = {}) noexcept = 0;
  // After start() with a multipart type: the next part, replacing an unsent one (counted as dropped). false once
  // the stream is closed or ended: forget the writer then.
  virtual bool push(StreamPart part) noexcept = 0;
  // No more parts: the host sends what is pending and closes the connection.
  virtual void end() noexcept = 0;
  // The client left, a write failed or stalled, the host stopped, or the answer is complete.
  virtual bool closed() const noexcept = 0;
  virtual StreamCounters counters() const noexcept = 0;
};

struct StreamRoute {
  std::string method = "GET";
  // As Route::path: absolute for standard capabilities ("/api/stream/mjpeg"), below /api/cap/<name> for custom ones.
  std::string path;
  Scope scope = Scope::Status;  // raised like Route::scope (control for custom capabilities and non-GET methods)
  // Runs on the capability's worker ("cap.<name>") like a Route's handler, under the same timeout: register the
  // client and return; write to `writer` later from any thread. It must answer (start or respond) within
  // runtime.handler_timeout_ms, else the client gets 503. Exceptions are caught: that request gets 500 (as a Route's).
  std::function<void(const Request&, std::shared_ptr<StreamWriter> writer)> handler;
};

}  // namespace rcand::sdk
