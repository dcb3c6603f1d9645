#include "kernel/safety/stop_summary.hpp"

namespace rcand::kernel {

std::string describe_stop(const Estop::Snapshot& snapshot) {
  if (!snapshot.estopped) return {};
  const auto& origin = snapshot.origin;
  const std::string said = origin.note.empty() ? "" : ": " + origin.note;
  if (origin.kind == "request") {
    std::string text = "Stopped by " + origin.principal;
    if (!origin.from.empty()) text += " from " + origin.from;
    return text + (said.empty() && origin.from.empty() ? " (POST /api/stop, no reason given)" : said);
  }
  if (origin.kind == "swarm")
    return "Stopped by a swarm broadcast forwarded by " + origin.from + " (as " + origin.principal + ")" + said;
  if (origin.kind == "plugin") return "Stopped by " + origin.from + said;
  if (origin.kind == "reload") return "Stopped by " + origin.principal + " to reload plugin " + origin.from;
  if (origin.kind == "shutdown") return "Stopped because rcand is shutting down";
  if (origin.kind == "startup") return "Latched at startup: " + (origin.note.empty() ? snapshot.reason : origin.note);
  return "Stopped: " + snapshot.reason + (snapshot.source.empty() ? "" : " (by " + snapshot.source + ")");
}

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
          {"summary", on ? json(describe_stop(snapshot)) : json()}};
}

}  // namespace rcand::kernel
