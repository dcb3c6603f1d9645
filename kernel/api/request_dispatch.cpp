#include "kernel/api/request_dispatch.hpp"

#include "libs/rcan/role_scopes.hpp"

namespace rcand::kernel {

void KernelRequestDispatcher::dispatch(sdk::Request request, std::function<void(sdk::Response)> done) const noexcept {
  try {
    const Principal principal{request.principal, request.role, default_scopes(request.role), "plugin"};
    http::Request http;
    http.method = std::move(request.method);
    http.target = http.path = std::move(request.path);
    http.query = std::move(request.query);
    if (!request.body.is_null()) http.body = request.body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    http.remote = "plugin";
    if (!request.message_id.empty()) http.headers["x-message-id"] = std::move(request.message_id);
    api_.execute(principal, std::move(http), [done](http::Response response) {
      // A stream or a binary body (a snapshot JPEG) has no JSON to hand back: the caller learns what it was.
      if (response.stream != nullptr || response.content_type != "application/json") {
        done(sdk::Response{response.status, {{"content_type", response.content_type}, {"bytes", response.body.size()}}});
        return;
      }
      auto body = nlohmann::json::parse(response.body, nullptr, false);
      done(sdk::Response{response.status, body.is_discarded() ? nlohmann::json::object() : std::move(body)});
    });
  } catch (const std::exception& e) {  // no memory: the request never ran
    done(sdk::Response::error(500, "INTERNAL", std::string("request not dispatched: ") + e.what()));
  }
}

}  // namespace rcand::kernel
