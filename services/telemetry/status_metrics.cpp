#include "services/telemetry/status_metrics.hpp"

#include <string>
#include <string_view>

#include "libs/base/json_body.hpp"
#include "services/telemetry/telemetry_frame.hpp"

namespace rcand::services::telemetry {
namespace {

using nlohmann::json;

std::string text_of(const json& doc, const char* key) {
  const auto it = doc.find(key);
  return it != doc.end() && it->is_string() ? it->get<std::string>() : std::string();
}

void one_hot(MetricsText& out, Labels labels, std::string_view current, std::initializer_list<std::string_view> states) {
  labels.emplace_back("state", "");
  for (const auto state : states) {
    labels.back().second = std::string(state);
    out.sample(labels, state == current ? 1 : 0);
  }
}

}  // namespace

void write_status_metrics(MetricsText& out, const json& status) {
  const json doc = status.is_object() ? status : json::object();
  out.family("rcand_info", "gauge", "always 1; the robot's identity and rcand's version as labels");
  out.sample({{"ruri", text_of(doc, "ruri")},
              {"name", text_of(doc, "name")},
              {"version", text_of(doc, "version")},
              {"rcan_version", text_of(doc, "rcan_version")}},
             1);
  out.family("rcand_uptime_seconds", "gauge", "seconds since rcand started");
  out.sample(doc.value("uptime_s", 0.0));
  out.family("rcand_estop_latched", "gauge", "1 while the e-stop is latched");
  out.sample(is_true(doc, "estopped") ? 1 : 0);
  out.family("rcand_robot_state", "gauge", "the robot's state (docs/protocol.md §5): 1 for the current one");
  one_hot(out, {}, text_of(doc, "state"), {"idle", "running", "error", "estop"});

  out.family("rcand_plugin_state", "gauge", "each plugin found at startup, by its load state: 1 for the current one");
  if (const auto it = doc.find("plugins"); it != doc.end() && it->is_array())
    for (const auto& plugin : *it)
      if (plugin.is_object()) out.sample({{"plugin", text_of(plugin, "id")}, {"state", text_of(plugin, "state")}}, 1);

  out.family("rcand_capability_state", "gauge",
             "each declared capability: ok, stale (its status not refreshed for 2 s), degraded (some actuators it needs "
             "failed), error (every actuator it needs failed, or it runs but reports a fault, such as a camera with no "
             "picture) or failed; 1 for the current one");
  if (const auto it = doc.find("capabilities"); it != doc.end() && it->is_object())
    for (const auto& [name, item] : it->items())
      one_hot(out, {{"capability", name}}, item_state(item), {"ok", "stale", "degraded", "error", "failed"});

  out.family("rcand_driver_state", "gauge", "each configured driver: ok, stale, error or failed; 1 for the current one");
  if (const auto it = doc.find("drivers"); it != doc.end() && it->is_array())
    for (const auto& item : *it)
      if (item.is_object()) one_hot(out, {{"driver", text_of(item, "id")}}, item_state(item), {"ok", "stale", "error", "failed"});

  out.family("rcand_nav_running", "gauge", "1 while a nav job drives the robot");
  out.sample(is_true(doc, "nav_running") ? 1 : 0);
}

}  // namespace rcand::services::telemetry
