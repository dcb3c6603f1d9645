// What a plugin's health is, from a status document (GET /api/status; docs/protocol.md §7.2, §7.14): the library's
// state says whether it loaded, its instances say whether what it serves here works. A loaded library whose only
// driver failed is not "ok". Plain JSON in, plain JSON out: the kernel's status board and its /api/plugins row use it.
#pragma once

#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace rcand {

// Each plugin's instances in `status_doc`, {"<plugin id>": [{"driver"|"capability": name, "state", "reason"?,
// "device"?, "os_error"?, "hint"?, "stale"?}]}, drivers first.
nlohmann::json instances_by_plugin(const nlohmann::json& status_doc);

// "error" when the library is not usable or an instance failed or is in error, "degraded" when one is, "unused" when
// it is not enabled or serves nothing here, else "ok".
std::string plugin_health(std::string_view library_state, const nlohmann::json& instances);

// Adds "instances" (when `with_instances`) and "health" to each item of `plugins` (each with "id" and "state"), from
// `status_doc`.
void add_plugin_health(nlohmann::json& plugins, const nlohmann::json& status_doc, bool with_instances);

}  // namespace rcand
