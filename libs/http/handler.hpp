// How the server hands a request to the kernel and how the kernel answers it.
#pragma once

#include <functional>

#include "libs/http/request.hpp"
#include "libs/http/response.hpp"

namespace rcand::http {

// Call exactly once, from any thread; later calls are ignored. Safe to call after the connection closed and after
// the Server was stopped or destroyed (the answer is then dropped). Never blocks. If every copy is destroyed without
// being called, the client gets a 500 INTERNAL.
using Respond = std::function<void(Response)>;

// Runs on an I/O thread. Must not block: answer inline or hand the work elsewhere and call respond later.
// An exception escaping it answers 500 INTERNAL (unless it already responded). It must not call Server::stop().
using Handler = std::function<void(Request&&, Respond)>;

}  // namespace rcand::http
