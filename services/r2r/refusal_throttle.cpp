#include "services/r2r/refusal_throttle.hpp"

#include <algorithm>
#include <vector>

namespace rcand::services::r2r {

// Each budget is asked only while the previous ones allow, so a refusal held back by one costs no other.
bool RefusalThrottle::Budget::admit(const std::string& sender, std::string_view address, std::int64_t now_us) {
  return !per_sender.admit(sender, now_us) && (address.empty() || !per_address.admit(address, now_us)) &&
         !total.admit("all", now_us);
}

RefusalThrottle::Verdict RefusalThrottle::admit(std::string_view sender, std::string_view address, bool answerable,
                                                std::int64_t now_us) {
  const std::string key(sender);
  Verdict verdict;
  verdict.log = log_.admit(key, address, now_us);
  verdict.answer = answerable && answers_.admit(key, address, now_us);
  if (verdict.log && (verdict.answer || !answerable)) return verdict;
  std::lock_guard lock(mutex_);
  if (since_us_ < 0) since_us_ = now_us;
  if (answerable && !verdict.answer) ++answers_held_back_;
  if (verdict.log) return verdict;
  if (const auto it = held_back_.find(sender); it != held_back_.end()) ++it->second;
  else if (held_back_.size() < kTalliedSenders) held_back_.emplace(std::string(sender), 1);
  else ++held_back_others_;
  return verdict;
}

std::optional<std::string> RefusalThrottle::summary(std::int64_t now_us) {
  std::lock_guard lock(mutex_);
  if (since_us_ < 0 || now_us - since_us_ < std::chrono::microseconds(kSummaryPeriod).count()) return std::nullopt;
  std::vector<std::pair<std::string, std::uint64_t>> senders(held_back_.begin(), held_back_.end());
  std::sort(senders.begin(), senders.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
  std::uint64_t total = held_back_others_, rest = held_back_others_;
  std::string named;
  for (std::size_t i = 0; i < senders.size(); ++i) {
    total += senders[i].second;
    if (i >= kSummaryNames) {
      rest += senders[i].second;
      continue;
    }
    named += (named.empty() ? "'" : ", '") + senders[i].first + "' (" + std::to_string(senders[i].second) + ")";
  }
  const std::size_t unnamed = senders.size() > kSummaryNames ? senders.size() - kSummaryNames : 0;
  if (rest > 0)
    named += (named.empty() ? "" : " and ") + std::to_string(rest) + " from " + (held_back_others_ > 0 ? "at least " : "") +
             std::to_string(unnamed + (held_back_others_ > 0 ? 1 : 0)) + " other senders";
  const auto seconds = std::to_string((now_us - since_us_ + 500'000) / 1'000'000);
  const std::string answers = std::to_string(answers_held_back_) + " error answers not sent (rate-limited)";
  std::string line = "r2r: " + answers + " in the last " + seconds + " s";
  if (total > 0)
    line = "r2r: suppressed " + std::to_string(total) + " refusals from " + named + " in the last " + seconds +
           " s (not logged one by one)" + (answers_held_back_ > 0 ? "; " + answers : "");
  held_back_.clear();
  held_back_others_ = answers_held_back_ = 0;
  since_us_ = -1;
  return line;
}

}  // namespace rcand::services::r2r
