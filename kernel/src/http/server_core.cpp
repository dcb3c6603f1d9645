#include "server_core.hpp"

#include <algorithm>

#include "http_logger.hpp"
#include "session.hpp"

namespace rcand::kernel::http::detail {

void IoSlot::track(std::weak_ptr<Session> session) {
  sessions_.push_back(std::move(session));
  if (sessions_.size() >= prune_at_) {
    std::erase_if(sessions_, [](const std::weak_ptr<Session>& s) { return s.expired(); });
    prune_at_ = std::max<std::size_t>(64, sessions_.size() * 2);
  }
}

void IoSlot::close_all() noexcept {
  for (auto& weak : sessions_) {
    if (auto session = weak.lock()) session->close();
  }
  sessions_.clear();
}

ServerCore::ServerCore(ServerOptions options_in, Handler handler_in)
    : options(std::move(options_in)), handler(std::move(handler_in)), log(http_logger()) {}

}  // namespace rcand::kernel::http::detail
