#include "kernel/audit/audit_log.hpp"

#include <algorithm>
#include <chrono>
#include <optional>
#include <vector>

#include "libs/base/bounded_text.hpp"

namespace rcand::kernel {
namespace {

nlohmann::json audit_entry_json(const AuditEntry& entry) {
  nlohmann::json item{{"seq", entry.seq},
                      {"principal", entry.principal},
                      {"ruri", entry.ruri},
                      {"timestamp_ms", entry.timestamp_ms},
                      {"message_id", entry.message_id},
                      {"event", entry.event},
                      {"outcome", entry.outcome}};
  if (!entry.detail.empty()) item["detail"] = entry.detail;
  if (entry.count > 1) {  // repeats coalesced into this entry
    item["count"] = entry.count;
    item["last_ms"] = entry.last_ms;
    item["last_message_id"] = entry.last_message_id;
  }
  if (entry.note.is_object())
    for (const auto& [key, value] : entry.note.items()) item.emplace(key, value);  // never over the entry's own
  return item;
}

std::int64_t audit_wall_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// The highest "seq" among the complete lines at the end of `file` (its last 64 KiB), 0 when there is none.
// Concurrent requests may write their lines slightly out of seq order, hence every line, not only the last.
std::uint64_t last_audit_seq(const std::filesystem::path& file) {
  std::uint64_t best = 0;
  for (const auto& text : RotatingFile::tail_lines(file)) {
    const auto line = nlohmann::json::parse(text, nullptr, false);
    if (line.is_object() && line.contains("seq") && line["seq"].is_number_unsigned())
      best = std::max(best, line["seq"].get<std::uint64_t>());
  }
  return best;
}

}  // namespace

bool AuditLog::log_line_allowed(const std::string& principal) noexcept {
  try {
    const auto verdict = log_limit_.admit(principal);
    if (verdict.log && verdict.suppressed > 0)
      logger("kernel.audit")
          ->warn("{} audit log lines for {} suppressed (more than {} a second; the audit log itself has them all)",
                 verdict.suppressed, principal, kLogLinesPerSecond);
    return verdict.log;
  } catch (...) {
    return false;
  }
}

void AuditLog::identify(std::string robot_ruri, const sdk::Clock& clock) {
  robot_ruri_ = std::move(robot_ruri);
  clock_ = &clock;
}

std::int64_t AuditLog::now_ms() const { return clock_ != nullptr ? clock_->wall_ms() : audit_wall_ms(); }

std::uint64_t AuditLog::begin(const std::string& principal, const std::string& message_id, std::string event, nlohmann::json note,
                              AuditRetention retention) {
  return record({0, principal, robot_ruri_, message_id, std::move(event), now_ms(), "pending", {}, std::move(note)}, retention);
}

void AuditLog::bound_fields(AuditEntry& entry) const {
  // Every field may carry what a client sent (a message id, an action type, a path): bounded before it is kept.
  entry.principal = bounded_text(entry.principal, kFieldLimit);
  entry.ruri = bounded_text(entry.ruri, kFieldLimit);
  entry.message_id = bounded_text(entry.message_id, kFieldLimit);
  entry.event = bounded_text(entry.event, kEventLimit);
  entry.outcome = bounded_text(entry.outcome, kFieldLimit);
  entry.detail = bounded_text(entry.detail, kDetailLimit);
}

// Under mutex_: gives `entry` its seq and keeps it in its ring (the ring's oldest goes when it is full).
std::uint64_t AuditLog::store_locked(AuditEntry& entry, AuditRetention retention) {
  Ring& ring = retention == AuditRetention::Stop ? stops_ : records_;
  entry.seq = next_seq_++;
  if (ring.capacity == 0) {
    ++ring.dropped;
    return entry.seq;
  }
  if (ring.entries.size() >= ring.capacity) {
    // A stop still pending when it leaves memory: its outcome line must still go to the stops file.
    if (&ring == &stops_ && ring.entries.front().outcome == "pending") {
      if (evicted_stops_.size() >= kMaxCoalesced) evicted_stops_.clear();
      evicted_stops_.insert(ring.entries.front().seq);
    }
    ring.entries.pop_front();
    ++ring.dropped;
  }
  ring.entries.push_back(entry);
  return entry.seq;
}

std::uint64_t AuditLog::record(AuditEntry entry, AuditRetention retention) {
  bound_fields(entry);
  std::uint64_t seq;
  {
    std::lock_guard lock(mutex_);
    seq = store_locked(entry, retention);
  }
  write_entry(entry, retention);  // before dispatch: a crash while the command runs leaves this pending line
  if (log_line_allowed(entry.principal))
    logger("kernel.audit")->info("#{} {} by {} ({})", seq, entry.event, entry.principal, entry.message_id);
  return seq;
}

std::uint64_t AuditLog::begin_stop(const std::string& principal, const std::string& message_id, std::string event, bool latched,
                                   std::string detail) {
  AuditEntry entry{0, principal, robot_ruri_, message_id, std::move(event), now_ms(), "pending", std::move(detail), nullptr};
  bound_fields(entry);
  const std::string key = entry.principal + '\n' + entry.event;
  std::optional<RepeatLine> due;
  std::uint64_t seq = 0;
  {
    std::lock_guard lock(mutex_);
    if (RepeatLine line; latched && coalesce_locked(key, entry.message_id, entry.timestamp_ms, line)) {
      if (line.seq != 0) due = std::move(line);
    } else {
      seq = store_locked(entry, AuditRetention::Stop);
      if (coalesced_.size() >= kMaxCoalesced && !coalesced_.contains(key)) coalesced_.clear();  // bounded: new entries
      coalesced_[key] = {seq, 1, entry.timestamp_ms};
    }
  }
  if (due) {  // a repeat: its count reaches the file at most once a second, and no log line
    write_repeat(*due);
    return 0;
  }
  if (seq == 0) return 0;
  write_entry(entry, AuditRetention::Stop);
  if (log_line_allowed(entry.principal))
    logger("kernel.audit")->info("#{} {} by {} ({})", seq, entry.event, entry.principal, entry.message_id);
  return seq;
}

// Under mutex_: counts a repeat into the open entry of `key`. False when there is none (or it left memory). `line`
// gets the count to write when the last one written is kRepeatLineGapMs old (else its seq stays 0).
bool AuditLog::coalesce_locked(const std::string& key, const std::string& message_id, std::int64_t now, RepeatLine& line) {
  const auto open = coalesced_.find(key);
  if (open == coalesced_.end()) return false;
  AuditEntry* entry = find_locked(open->second.seq);
  if (entry == nullptr) {
    coalesced_.erase(open);
    return false;
  }
  ++entry->count;
  entry->last_ms = now;
  entry->last_message_id = message_id;
  Coalesced& state = open->second;
  if (state.count_in_file == 1 || now - state.written_ms >= kRepeatLineGapMs) {
    line = {entry->seq, entry->count, now, message_id};
    state.count_in_file = entry->count;
    state.written_ms = now;
  }
  return true;
}

void AuditLog::end_repeats() noexcept {
  try {
    std::vector<RepeatLine> pending;
    {
      std::lock_guard lock(mutex_);
      for (const auto& [key, state] : coalesced_)
        if (const AuditEntry* entry = find_locked(state.seq); entry != nullptr && entry->count != state.count_in_file)
          pending.push_back({entry->seq, entry->count, entry->last_ms, entry->last_message_id});
      coalesced_.clear();
    }
    for (const auto& line : pending) write_repeat(line);
  } catch (...) {  // no memory: the counts stay in memory (GET /api/audit)
  }
}

AuditEntry* AuditLog::find_locked(std::uint64_t seq, bool* is_stop) {
  for (Ring* ring : {&records_, &stops_}) {
    auto& entries = ring->entries;
    const auto it =
        std::lower_bound(entries.begin(), entries.end(), seq, [](const AuditEntry& e, std::uint64_t s) { return e.seq < s; });
    if (it == entries.end() || it->seq != seq) continue;
    if (is_stop != nullptr) *is_stop = ring == &stops_;
    return &*it;
  }
  return nullptr;
}

void AuditLog::finish(std::uint64_t seq, std::string outcome, std::string detail) {
  if (seq == 0) return;  // a coalesced repeat
  outcome = bounded_text(outcome, kFieldLimit);
  detail = bounded_text(detail, kDetailLimit);
  std::optional<AuditEntry> finished;
  bool stop = false;
  {
    std::lock_guard lock(mutex_);
    if (AuditEntry* entry = find_locked(seq, &stop)) {
      entry->outcome = outcome;
      entry->detail = detail;
      finished = *entry;
    } else {
      stop = evicted_stops_.erase(seq) > 0;
    }
  }
  nlohmann::json line;
  if (finished) {
    line = audit_entry_json(*finished);
  } else {  // already rotated out of memory: the outcome alone, under the same seq
    line = {{"seq", seq}, {"outcome", outcome}};
    if (!detail.empty()) line["detail"] = detail;
  }
  line["kind"] = "outcome";
  line["finished_ms"] = audit_wall_ms();
  append_line(stop ? stops_file_ : records_file_, seq, line);
  if (log_line_allowed(finished ? finished->principal : std::string("?")))
    logger("kernel.audit")->info("#{} {}{}{}", seq, outcome, detail.empty() ? "" : ": ", detail);
}

AuditLog::~AuditLog() { end_repeats(); }

void AuditLog::write_entry(const AuditEntry& entry, AuditRetention retention) noexcept {
  try {
    RotatingFile& file = retention == AuditRetention::Stop ? stops_file_ : records_file_;
    if (!file.is_open()) return;
    auto line = audit_entry_json(entry);
    line["kind"] = "entry";
    append_line(file, entry.seq, line);
  } catch (...) {
  }
}

void AuditLog::write_repeat(const RepeatLine& repeat) noexcept {
  try {
    if (stops_file_.is_open())
      append_line(stops_file_, repeat.seq,
                  {{"kind", "repeat"},
                   {"seq", repeat.seq},
                   {"count", repeat.count},
                   {"last_ms", repeat.last_ms},
                   {"last_message_id", repeat.last_message_id}});
    logger("kernel.audit")
        ->info("#{} repeated: {} stops so far, the last at {} ({})", repeat.seq, repeat.count, repeat.last_ms,
               repeat.last_message_id);
  } catch (...) {
  }
}

std::filesystem::path AuditLog::stops_file_for(const std::filesystem::path& file) {
  return file.parent_path() / (file.stem().string() + ".stops" + file.extension().string());
}

void AuditLog::persist_to(const std::filesystem::path& file, std::uintmax_t max_bytes, int keep) {
  const auto stops = stops_file_for(file);
  records_file_.open(file, max_bytes, keep, "runtime.audit_file");
  stops_file_.open(stops, max_bytes, keep, "runtime.audit_file (its stops file)");
  // Continue the sequence: from the files, or from the last rotated ones when they were just started.
  std::uint64_t last = 0;
  for (const auto& name : {file, stops}) {
    std::uint64_t found = last_audit_seq(name);
    if (found == 0) found = last_audit_seq(RotatingFile::rotated_name(name, 1));
    last = std::max(last, found);
  }
  std::lock_guard lock(mutex_);
  if (records_.entries.empty() && stops_.entries.empty() && last >= next_seq_) next_seq_ = first_seq_ = last + 1;
}

void AuditLog::append_line(RotatingFile& file, std::uint64_t seq, const nlohmann::json& line_json) noexcept {
  try {
    if (!file.is_open()) return;
    const std::string line = line_json.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
    if (!file.append(line)) logger("kernel.audit")->error("cannot write audit entry #{} to {}", seq, file.name());
  } catch (...) {
  }
}

std::uint64_t AuditLog::dropped() const {
  std::lock_guard lock(mutex_);
  return records_.dropped + stops_.dropped;
}

nlohmann::json AuditLog::to_json(std::size_t limit) const {
  nlohmann::json list = nlohmann::json::array();
  std::lock_guard lock(mutex_);
  auto record = records_.entries.rbegin();
  auto stop = stops_.entries.rbegin();
  while (list.size() < limit && (record != records_.entries.rend() || stop != stops_.entries.rend())) {
    const bool take_stop = record == records_.entries.rend() || (stop != stops_.entries.rend() && stop->seq > record->seq);
    list.push_back(audit_entry_json(take_stop ? *stop++ : *record++));
  }
  nlohmann::json doc{{"entries", std::move(list)},
                     {"total", next_seq_ - first_seq_},
                     {"dropped", records_.dropped + stops_.dropped},
                     {"dropped_stops", stops_.dropped}};
  if (records_file_.is_open()) {
    doc["file"] = records_file_.name();
    doc["stops_file"] = stops_file_.name();
  }
  return doc;
}

std::uint64_t AuditLog::total() const {
  std::lock_guard lock(mutex_);
  return next_seq_ - first_seq_;
}

}  // namespace rcand::kernel
