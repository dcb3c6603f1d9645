// The thought log behind GET /api/thoughts/<id>: what each instruction became - who asked, the brain that answered
// (and the ones that failed), its reading, action and confidence, the gates' verdicts, the HiTL decision and the
// dispatched result. A ring of the last `capacity` thoughts, so memory stays bounded however long rcand runs; every
// stored text is bounded too. The brain's `reasoning` is kept apart: get() adds it only for callers whose role has
// scope `config` (a model's chain of thought may echo the prompt and other principals' instructions).
#pragma once

#include <rcand/sdk/http.hpp>

#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>

namespace rcand::plugins::chat {

class ThoughtLog {
 public:
  explicit ThoughtLog(std::size_t capacity) : capacity_(capacity == 0 ? 1 : capacity) {}

  // Records a new thought (the oldest one leaves when full).
  void add(const std::string& id, sdk::Json thought);
  // Merges `fields` into the thought (a no-op once it left the ring); `reasoning` replaces the kept one when given.
  void update(const std::string& id, const sdk::Json& fields, std::optional<std::string> reasoning = std::nullopt);
  // The thought, with "reasoning" when `with_reasoning`; nullopt when unknown or no longer kept.
  std::optional<sdk::Json> get(const std::string& id, bool with_reasoning) const;
  std::size_t size() const;
  std::size_t capacity() const noexcept { return capacity_; }

 private:
  struct Entry {
    sdk::Json thought;
    std::string reasoning;
  };
  const std::size_t capacity_;
  mutable std::mutex mutex_;
  std::deque<std::string> order_;  // oldest first
  std::unordered_map<std::string, Entry> entries_;
};

// A JSON value for the log: kept as is when its text is at most `max_chars`, else {"truncated": true, "chars": n}
// (a model may propose megabytes; the thought only needs to show what it was).
sdk::Json bounded_json(const sdk::Json& value, std::size_t max_chars = 4096);

}  // namespace rcand::plugins::chat
