#include "kernel/safety/stop_summary.hpp"

namespace rcand::kernel {

nlohmann::json estop_document(const Estop::Snapshot& snapshot) {
  using nlohmann::json;
  const bool on = snapshot.estopped;
  const auto text_or_null = [on](const std::string& text) { return on && !text.empty() ? json(text) : json(); };
  return {{"estopped", on},
          {"since_ms", on ? json(snapshot.since_ms) : json()},
          {"reason", on ? json(snapshot.reason) : json()},
          {"source", on ? json(snapshot.source) : json()},
          {"principal", text_or_null(snapshot.origin.principal)},
          {"origin", text_or_null(snapshot.origin.kind)},
          {"from", text_or_null(snapshot.origin.from)},
          {"summary", on ? json(describe_stop(snapshot.origin, snapshot.reason, snapshot.source)) : json()}};
}

}  // namespace rcand::kernel
