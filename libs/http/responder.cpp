#include "libs/http/responder.hpp"

#include <boost/asio/dispatch.hpp>

#include "libs/http/session.hpp"

namespace rcand::http::detail {

Responder::Responder(std::shared_ptr<Session> session)
    : core_(session->core().shared_from_this()), session_(std::move(session)) {}

Responder::~Responder() {
  if (used_.load(std::memory_order_acquire)) return;
  try {
    respond(error_response(500, "INTERNAL", "the request was dropped without an answer"));
  } catch (...) {  // out of memory while giving up on a request: the connection just closes
  }
}

void Responder::respond(Response response) {
  if (used_.exchange(true, std::memory_order_acq_rel)) return;
  auto session = std::move(session_);
  // Inline when already on the session's loop (the common, fast case); queued otherwise. A stopped loop never runs
  // it, and destroys it with the loop.
  auto executor = session->executor();
  boost::asio::dispatch(
      executor, [session = std::move(session), response = std::move(response)]() mutable { session->send(std::move(response)); });
}

}  // namespace rcand::http::detail
