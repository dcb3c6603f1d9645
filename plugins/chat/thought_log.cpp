#include "thought_log.hpp"

namespace rcand::plugins::chat {

void ThoughtLog::add(const std::string& id, sdk::Json thought) {
  std::lock_guard lock(mutex_);
  if (entries_.contains(id)) return;
  while (order_.size() >= capacity_) {
    entries_.erase(order_.front());
    order_.pop_front();
  }
  order_.push_back(id);
  entries_[id].thought = std::move(thought);
}

void ThoughtLog::update(const std::string& id, const sdk::Json& fields, std::optional<std::string> reasoning) {
  std::lock_guard lock(mutex_);
  const auto it = entries_.find(id);
  if (it == entries_.end()) return;
  it->second.thought.update(fields);
  if (reasoning) it->second.reasoning = std::move(*reasoning);
}

std::optional<sdk::Json> ThoughtLog::get(const std::string& id, bool with_reasoning) const {
  std::lock_guard lock(mutex_);
  const auto it = entries_.find(id);
  if (it == entries_.end()) return std::nullopt;
  sdk::Json thought = it->second.thought;
  if (with_reasoning) thought["reasoning"] = it->second.reasoning;
  return thought;
}

std::size_t ThoughtLog::size() const {
  std::lock_guard lock(mutex_);
  return order_.size();
}

sdk::Json bounded_json(const sdk::Json& value, std::size_t max_chars) {
  const std::string text = value.dump(-1, ' ', false, sdk::Json::error_handler_t::replace);  // never throws on bad UTF-8
  if (text.size() <= max_chars) return value;
  return {{"truncated", true}, {"chars", text.size()}};
}

}  // namespace rcand::plugins::chat
