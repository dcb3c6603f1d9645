// The state behind a Respond: answers once, from any thread, by dispatching onto the session's event loop.
#pragma once

#include <atomic>
#include <memory>

#include "libs/http/response.hpp"
#include "libs/http/server_core.hpp"

namespace rcand::http::detail {

class Session;

class Responder {
 public:
  explicit Responder(std::shared_ptr<Session> session);
  // Dropped unanswered: the client still gets an answer (500) instead of a connection that hangs.
  ~Responder();
  Responder(const Responder&) = delete;
  Responder& operator=(const Responder&) = delete;

  // Any thread; the first call wins, later ones are ignored.
  void respond(Response response);

 private:
  // core_ is declared first so it is released last: the session's socket belongs to one of its event loops.
  std::shared_ptr<ServerCore> core_;
  std::shared_ptr<Session> session_;
  std::atomic<bool> used_{false};
};

}  // namespace rcand::http::detail
