#include "libs/http/server_core.hpp"

#include <algorithm>

#include "libs/http/http_logger.hpp"
#include "libs/http/session.hpp"

namespace rcand::http::detail {

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

bool ServerCore::fits(const std::string& address) const {
  if (connections.load(std::memory_order_relaxed) >= options.max_connections) return false;
  std::lock_guard lock(address_mutex_);
  const auto it = per_address_.find(address);
  return it == per_address_.end() || it->second < options.max_connections_per_address;
}

void ServerCore::count_address(const std::string& address, int delta) {
  std::lock_guard lock(address_mutex_);
  if (delta > 0) {
    ++per_address_[address];
    return;
  }
  const auto it = per_address_.find(address);
  if (it != per_address_.end() && --it->second == 0) per_address_.erase(it);
}

IoSlot& ServerCore::next_worker() noexcept {
  const std::size_t workers = slots.size() - 1;
  return *slots[1 + next_worker_.fetch_add(1, std::memory_order_relaxed) % workers];
}

bool ServerCore::is_priority(const Request& request) const { return options.priority && options.priority(request); }

ServerCore::ServerCore(ServerOptions options_in, Handler handler_in)
    : options(std::move(options_in)), handler(std::move(handler_in)), log(http_logger()) {}

}  // namespace rcand::http::detail
