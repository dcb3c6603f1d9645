#include "libs/r2r_wire/error_code.hpp"

#include "libs/base/bounded_text.hpp"

namespace rcand::r2r_wire {

std::string_view error_code_name(int code) noexcept {
  switch (code) {
    case 100: return "invalid_format";
    case 101: return "unknown_target";
    case 102: return "task_already_assigned";
    case 103: return "unauthorized";
    case 104: return "network_timeout";
    case 105: return "estop_active";
    default: return "unknown";
  }
}

nlohmann::json make_error_payload(ErrorCode code, std::string message, const std::optional<nlohmann::json>& ref) {
  if (message.size() > kMaxErrorMessageBytes) message = bounded_text(message, kMaxErrorMessageBytes);
  nlohmann::json payload{{"code", static_cast<int>(code)}, {"message", std::move(message)}};
  if (ref) payload["ref"] = error_ref(*ref);
  return payload;
}

nlohmann::json error_ref(const nlohmann::json& header) {
  constexpr std::size_t kMaxRefTextBytes = 256;  // kMaxIdBytes: an id longer than that was refused anyway
  nlohmann::json ref = nlohmann::json::object();
  if (!header.is_object()) return ref;
  for (const char* key : {"version", "timestamp", "source_id", "target_id"}) {
    const auto it = header.find(key);
    if (it == header.end()) continue;
    if (it->is_string()) ref[key] = bounded_text(it->get_ref<const std::string&>(), kMaxRefTextBytes);
    else if (it->is_number() || it->is_boolean()) ref[key] = *it;
  }
  return ref;
}

}  // namespace rcand::r2r_wire
