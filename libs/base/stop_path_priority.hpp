// The threads a stop runs on (the HTTP accept thread, which reads and handles every stop, and the halt crew) are
// real-time (SCHED_FIFO at runtime.stop_path_priority), so a stop does not wait for the scheduler behind work that
// saturates the cores. Measured (README, "Stop under load"): a fresh-connection stop while GET /api/status saturates
// both cores, p99 2.2 ms without, 0.7 ms with. The threads only wake for a stop or a new connection.
#pragma once

#include <string>

namespace rcand {

// Calling thread. 0 leaves it as it is. Returns "" when done, else why not (not permitted: the unit needs
// LimitRTPRIO= or CAP_SYS_NICE); the first failure in the process is also logged as a warning naming the fix.
std::string enter_stop_path_priority(int priority) noexcept;

// Calling thread: SCHED_BATCH, for threads the stop path wakes but does not wait for (the capabilities' on_estop()
// crew): a batch thread never preempts the running thread when it wakes, so waking one costs the stop path only
// the wake-up call (a normal thread that slept took the waker's CPU at once: ~50 us per stop, measured), and it
// still gets its fair share of the CPU right after. Needs no privilege; false when the kernel refused it.
bool enter_batch_policy() noexcept;
// Calling thread: SCHED_BATCH at nice 10, for work that follows a stop but has no deadline of its own (the state
// dir's writer, whose record the running marker already covers): it runs when the stop's client and the stop's
// own follow-ups leave a CPU, yet still gets ~10 % of a saturated core, so it is never starved for good.
bool enter_background_policy() noexcept;

}  // namespace rcand
