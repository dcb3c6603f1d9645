#include "libs/base/stop_origin.hpp"

namespace rcand {

std::string describe_stop(const StopOrigin& origin, const std::string& reason, const std::string& source) {
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
  if (origin.kind == "startup") return "Latched at startup: " + (origin.note.empty() ? reason : origin.note);
  return "Stopped: " + reason + (source.empty() ? "" : " (by " + source + ")");
}

}  // namespace rcand
