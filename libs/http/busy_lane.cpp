#include "libs/http/busy_lane.hpp"

#include <map>
#include <string>
#include <tuple>
#include <unordered_map>

#include "libs/http/target.hpp"

namespace rcand::http::detail {

PendingInput classify_pending(std::string_view bytes, const std::function<bool(const Request&)>& is_priority) {
  if (bytes.empty()) return PendingInput::Silent;
  // "METHOD SP target SP": the target ends at the second space; before it arrives the line is partial.
  const auto method_end = bytes.find(' ');
  const auto target_end = method_end == std::string_view::npos ? method_end : bytes.find(' ', method_end + 1);
  if (target_end == std::string_view::npos) {
    const bool line_ended = bytes.find('\n') != std::string_view::npos;
    return line_ended ? PendingInput::Ordinary : PendingInput::Partial;  // a broken line is answered 400
  }
  Request request;
  request.method = std::string(bytes.substr(0, method_end));
  request.target = std::string(bytes.substr(method_end + 1, target_end - method_end - 1));
  std::map<std::string, std::string> query;
  if (!parse_target(request.target, request.path, query).empty()) return PendingInput::Ordinary;
  return is_priority && is_priority(request) ? PendingInput::Priority : PendingInput::Ordinary;
}

std::optional<std::size_t> choose_eviction(std::span<const LaneWaiter> lane, std::string_view newcomer) {
  std::unordered_map<std::string_view, std::size_t> share;
  for (const auto& waiter : lane) ++share[waiter.address];
  // Lower is given up first: (input, not the newcomer's address, fewer of the lane's places, younger).
  auto rank = [&](const LaneWaiter& waiter) {
    const bool own = waiter.address == newcomer;
    return std::tuple(static_cast<int>(waiter.input), !own, own ? 0 : lane.size() - share[waiter.address]);
  };
  std::optional<std::size_t> chosen;
  for (std::size_t i = 0; i < lane.size(); ++i) {
    if (lane[i].input == PendingInput::Priority) continue;
    if (!chosen || rank(lane[i]) < rank(lane[*chosen])) chosen = i;  // strict: the oldest wins a tie
  }
  return chosen;
}

}  // namespace rcand::http::detail
