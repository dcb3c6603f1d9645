#include "services/telemetry/telemetry_frame.hpp"

#include <cmath>

#include "libs/base/json_body.hpp"

namespace rcand::services::telemetry {

using nlohmann::json;

std::string_view item_state(const json& item) {
  if (!item.is_object()) return "failed";
  const std::string state = item.value("state", std::string());
  for (std::string_view bad : {"failed", "error", "degraded"})
    if (state == bad) return bad;
  return is_true(item, "stale") ? "stale" : "ok";
}

json obstacles_field(const sdk::ObstacleSource* source) {
  if (source == nullptr) return nullptr;
  const sdk::ObstacleReading reading = source->obstacles();
  if (!reading.available) return nullptr;
  // A zone with no depth at all reads as infinity, which JSON cannot carry: null says "nothing seen" there.
  auto cm = [](double value) { return std::isfinite(value) ? json(value) : json(nullptr); };
  return {{"left_cm", cm(reading.left_cm)},
          {"center_cm", cm(reading.center_cm)},
          {"right_cm", cm(reading.right_cm)},
          {"nearest_cm", cm(reading.nearest_cm)},
          {"timestamp_ms", reading.timestamp_ms}};
}

namespace {

json battery_volts(const json& capabilities) {
  if (!capabilities.is_object()) return nullptr;
  for (const auto& [name, item] : capabilities.items()) {
    if (!item.is_object() || !item.contains("status") || !item["status"].is_object()) continue;
    const json& status = item["status"];
    if (const auto it = status.find("battery_v"); it != status.end() && it->is_number()) return *it;
  }
  return nullptr;
}

bool flag(const json& status, const char* key) { return is_true(status, key); }

}  // namespace

json telemetry_frame(const json& status, const FrameContext& context) {
  const json empty = json::object();
  const json& doc = status.is_object() ? status : empty;
  json capabilities = json::object();
  if (const auto it = doc.find("capabilities"); it != doc.end() && it->is_object())
    for (const auto& [name, item] : it->items()) capabilities[name] = item_state(item);
  json drivers = json::object();
  if (const auto it = doc.find("drivers"); it != doc.end() && it->is_array())
    for (const auto& item : *it)
      if (item.is_object() && item.contains("id") && item["id"].is_string())
        drivers[item["id"].get<std::string>()] = item_state(item);
  const auto pose = doc.find("pose");
  const auto uptime = doc.find("uptime_s");
  const auto state = doc.find("state");
  return {{"type", "telemetry"},
          {"seq", context.seq},
          {"event", context.event},
          {"ts", context.ts_ms},
          {"loop_latency_ms", nullptr},
          {"loop_count", nullptr},
          {"paused", false},
          {"estopped", flag(doc, "estopped")},
          {"nav_running", flag(doc, "nav_running")},
          {"obstacles", context.obstacles},
          {"battery_v", battery_volts(doc.contains("capabilities") ? doc["capabilities"] : json())},
          {"state", state != doc.end() && state->is_string() ? *state : json(nullptr)},
          {"uptime_s", uptime != doc.end() && uptime->is_number() ? *uptime : json(nullptr)},
          {"pose", pose != doc.end() && pose->is_object() ? *pose : json(nullptr)},
          {"capabilities", std::move(capabilities)},
          {"drivers", std::move(drivers)},
          {"estop", context.estop}};
}

}  // namespace rcand::services::telemetry
