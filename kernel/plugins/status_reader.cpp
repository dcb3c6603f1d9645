#include "kernel/plugins/status_reader.hpp"

#include "kernel/plugins/guarded.hpp"
#include "libs/base/logging.hpp"

namespace rcand::kernel {
namespace {

std::vector<DeadlineCrew::Job> jobs_for(const std::vector<StatusReader::Source>& sources,
                                        const std::vector<std::shared_ptr<StatusReader::Slot>>& slots) {
  std::vector<DeadlineCrew::Job> jobs;
  for (std::size_t i = 0; i < sources.size(); ++i)
    jobs.push_back({sources[i].who, [who = sources[i].who, status = sources[i].status, slot = slots[i]] {
                      std::string failure;
                      auto value = guarded_result(who, "status", failure, status);
                      std::lock_guard lock(slot->mutex);
                      slot->latest = std::move(value);
                      slot->in_flight.store(false);
                    }});
  return jobs;
}

std::vector<std::shared_ptr<StatusReader::Slot>> make_slots(std::size_t count) {
  std::vector<std::shared_ptr<StatusReader::Slot>> slots;
  for (std::size_t i = 0; i < count; ++i) slots.push_back(std::make_shared<StatusReader::Slot>());
  return slots;
}

std::int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

StatusReader::StatusReader(std::vector<Source> sources)
    : sources_(std::move(sources)), slots_(make_slots(sources_.size())), crew_("status", jobs_for(sources_, slots_)) {}

std::vector<std::optional<nlohmann::json>> StatusReader::read(std::span<const std::size_t> indices) {
  std::vector<std::optional<nlohmann::json>> values(indices.size());
  std::vector<std::size_t> asked;  // positions in `indices` this call starts and waits for
  std::vector<std::size_t> asked_sources;
  for (std::size_t i = 0; i < indices.size(); ++i) {
    const std::size_t index = indices[i];
    if (index >= slots_.size() || slots_[index]->hung.load()) continue;
    auto& slot = *slots_[index];
    if (slot.in_flight.exchange(true)) {  // the call asked earlier has not returned: its last value, at once
      if (steady_ns() - slot.asked_ns.load() > std::chrono::nanoseconds(kHungAfter).count()) {
        mark_hung(index, "status() did not return within " + std::to_string(kHungAfter.count()) + " ms (it must not block)");
        continue;
      }
      std::lock_guard lock(slot.mutex);
      values[i] = slot.latest;
      continue;
    }
    slot.asked_ns.store(steady_ns());
    asked.push_back(i);
    asked_sources.push_back(index);
  }
  const auto outcomes = crew_.run_some(asked_sources, std::chrono::steady_clock::now() + kStatusDeadline);

  for (std::size_t a = 0; a < asked.size(); ++a) {
    const std::size_t index = asked_sources[a];
    const auto state = a < outcomes.size() ? outcomes[a].state : DeadlineCrew::State::Pending;
    if (state == DeadlineCrew::State::Failed) {
      mark_hung(index, "status() ended the thread: " + outcomes[a].error);
      continue;
    }
    auto& slot = *slots_[index];  // Done, or late: the last value it returned (a late call finishes on its own)
    std::lock_guard lock(slot.mutex);
    values[asked[a]] = slot.latest;
  }
  return values;
}

void StatusReader::mark_hung(std::size_t index, const std::string& why) {
  if (slots_[index]->hung.exchange(true)) return;  // another reader already reported it
  const auto& source = sources_[index];
  logger("kernel.plugins")->error("{}: {}", source.who, why);
  if (source.health != nullptr) source.health->mark_failed(why);
}

std::optional<nlohmann::json> StatusReader::read(std::size_t index) {
  const std::size_t indices[] = {index};
  return std::move(read(indices).front());
}

bool StatusReader::quiesce(std::chrono::milliseconds grace) noexcept { return crew_.quiesce(grace); }

}  // namespace rcand::kernel
