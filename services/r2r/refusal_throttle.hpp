// How often one sender's refused R2R messages are logged and answered (docs/protocol.md §11.12; issue 28 #9, issue
// 31): refusals cost the refusing robot a log line and an `error` on the wire, so a sender that keeps sending what
// is refused - a flood of anonymous messages, a robot without the fleet's keys broadcasting its status every second
// - would otherwise get one of each per message. Per sender (the message's source_id, with the transport-level
// sender when there is one), and per transport-level sender as well (a UDP datagram's IP address, a WebSocket
// connection; MQTT's broker hides it), so cycling source_ids from one address gains nothing; and for all senders
// together, so cycling them everywhere gains nothing either:
//   log lines      kLogBurst per sender, then one per kLogGap; kTotalLogBurst for everyone, then kTotalLogPerSecond
//   error answers  kAnswerBurst per sender, then kAnswersPerSecond; kTotalAnswerBurst, then kTotalAnswersPerSecond
// What was held back is summed up in one log line per kSummaryPeriod at most ("suppressed N refusals from 'x' (n),
// ... in the last T s"), naming the senders that had the most. Any thread; short locks, never around I/O.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>

#include "libs/base/rate_limiter.hpp"

namespace rcand::services::r2r {

class RefusalThrottle {
 public:
  static constexpr double kLogBurst = 3;
  static constexpr std::chrono::seconds kLogGap{60};
  static constexpr double kTotalLogBurst = 50;
  static constexpr double kTotalLogPerSecond = 10;
  static constexpr double kAnswerBurst = 10;
  static constexpr double kAnswersPerSecond = 1;
  static constexpr double kTotalAnswerBurst = 100;
  static constexpr double kTotalAnswersPerSecond = 50;
  static constexpr std::chrono::seconds kSummaryPeriod{10};
  static constexpr std::size_t kSummaryNames = 3;      // senders named in a summary line
  static constexpr std::size_t kTalliedSenders = 256;  // senders counted by name; the rest count as "others"

  struct Verdict {
    bool log = false;
    bool answer = false;
  };

  // A refusal from `sender` (bounded by the caller), over `address` (empty: unknown). `answerable`: whether an error
  // answer would be sent at all (never to a broadcast, never to an `error`); only then is the answer budget used.
  Verdict admit(std::string_view sender, std::string_view address, bool answerable, std::int64_t now_us);
  // The summary of what was held back, once kSummaryPeriod has passed since the first of it; nullopt otherwise.
  std::optional<std::string> summary(std::int64_t now_us);

 private:
  static RateLimit per_second(double burst, double per_s) { return {per_s, burst / per_s}; }

  struct Budget {  // one kind of cost (log lines or error answers): per sender, per address, for everyone
    RateLimiter per_sender, per_address, total;
    Budget(double burst, double per_s, double total_burst, double total_per_s)
        : per_sender(per_second(burst, per_s)),
          per_address(per_second(burst, per_s)),
          total(per_second(total_burst, total_per_s), 1) {}
    bool admit(const std::string& sender, std::string_view address, std::int64_t now_us);
  };
  Budget log_{kLogBurst, 1.0 / static_cast<double>(kLogGap.count()), kTotalLogBurst, kTotalLogPerSecond};
  Budget answers_{kAnswerBurst, kAnswersPerSecond, kTotalAnswerBurst, kTotalAnswersPerSecond};

  std::mutex mutex_;                                             // the tallies below
  std::map<std::string, std::uint64_t, std::less<>> held_back_;  // refusals not logged, per sender
  std::uint64_t held_back_others_ = 0;                           // from senders beyond kTalliedSenders
  std::uint64_t answers_held_back_ = 0;
  std::int64_t since_us_ = -1;  // the first refusal held back since the last summary; -1: none
};

}  // namespace rcand::services::r2r
