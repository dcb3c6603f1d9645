// Human-in-the-loop (RCAN agent.hitl_gates[], the gate after the confidence gate): an action a gate names - or one a
// confidence gate escalates - waits for an OWNER's POST /api/hitl/authorize instead of being dispatched. The
// instruction's caller is answered at once (202, with the thought id); the decision, and the dispatched result, go
// to the thought log. A wait ends by approval, denial, its timeout (denied unless the gate says on_timeout: approve),
// or the e-stop (every waiting action is dropped: nothing decided before a stop runs after it). An approved action
// still passes the e-stop epoch check before it is dispatched, as the instruction's caller.
//
// Ruling (RCAN names the list, not its items): each gate is
//   {capabilities: [names] (optional: every capability), scope: status | control (optional: actions needing that
//    scope), timeout_ms: 1..3,600,000 (default 30,000), on_timeout: deny | approve (default deny)}
// A stop (POST /api/stop) never waits for a human.
#pragma once

#include <rcand/sdk/config_view.hpp>
#include <rcand/sdk/http.hpp>
#include <rcand/sdk/scope.hpp>

#include <chrono>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace rcand::plugins::chat {

struct HitlGate {
  std::vector<std::string> capabilities;  // empty: every capability
  std::optional<sdk::Scope> scope;
  std::chrono::milliseconds timeout{30000};
  bool approve_on_timeout = false;
};

// agent.hitl_gates of the robot config (absent: none). Throws sdk::ConfigError naming the item at fault.
std::vector<HitlGate> read_hitl_gates(const sdk::ConfigView& robot_config);

// The first gate that holds an action of `capability` needing `scope`, or null.
const HitlGate* matching_hitl_gate(const std::vector<HitlGate>& gates, sdk::Scope scope, const std::string& capability);

// The waiting actions. Thread-safe; never blocks beyond a brief lock. Exactly one decision reaches each wait: the
// first take() of its id wins (an approval racing the timeout or an e-stop).
//
// Shares (docs/protocol.md §7.5): the queue holds `limit` waits. A principal below OWNER holds at most `per_principal`
// of them, and the last `reserved` slots are only for OWNER and CREATOR - so one USER (or a few) can never fill the
// queue and have the OWNER's own gated instructions refused.
class HitlQueue {
 public:
  enum class Decision { Approve, Deny, Timeout, Estop, Shutdown };
  enum class Admission { Added, Full, OverShare, Reserved };
  struct Limits {
    std::size_t limit = 32;         // waits at once
    std::size_t per_principal = 8;  // of one principal below OWNER
    std::size_t reserved = 8;       // the last slots, for OWNER and CREATOR only
  };
  // Runs the decision (on the deciding thread, never blocking); `by` is the deciding principal ("" for a timeout or
  // the e-stop); `reply`, when set, answers the approver (POST /api/hitl/authorize).
  using Reply = std::function<void(sdk::Response)>;
  using Decide = std::function<void(Decision, const std::string& by, const std::string& reason, Reply reply)>;

  explicit HitlQueue(Limits limits) : limits_(limits) {}
  // Added, or why not: Full (no slot left), OverShare (`principal` holds its share already), Reserved (only reserved
  // slots are left and `privileged` - OWNER or CREATOR - is false).
  // `epoch`: the e-stop epoch the instruction came in under (take_all() reaches only older ones).
  Admission add(const std::string& thought_id, sdk::Json summary, Decide decide, std::uint64_t epoch,
                const std::string& principal, bool privileged);
  const Limits& limits() const noexcept { return limits_; }
  // Attaches the wait's timeout timer; false when it was decided meanwhile (the caller cancels the timer).
  bool set_timer(const std::string& thought_id, std::uint64_t timer);
  // The wait's decision function and its timer, removed; nullopt when it is not waiting (unknown, or decided).
  struct Taken {
    Decide decide;
    std::uint64_t timer = 0;
  };
  std::optional<Taken> take(const std::string& thought_id);
  // The waits that came in before `epoch` (all by default).
  std::vector<Taken> take_all(std::uint64_t epoch = std::numeric_limits<std::uint64_t>::max());
  sdk::Json list() const;  // the summaries, oldest first
  std::size_t size() const;

 private:
  struct Wait {
    std::uint64_t seq;
    sdk::Json summary;
    Decide decide;
    std::uint64_t timer;
    std::uint64_t epoch;
    std::string principal;
  };
  const Limits limits_;
  mutable std::mutex mutex_;
  std::uint64_t seq_ = 0;
  std::map<std::string, Wait> waits_;
};

const char* decision_name(HitlQueue::Decision decision) noexcept;

}  // namespace rcand::plugins::chat
