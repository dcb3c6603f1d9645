#include "rcand/kernel/r2r/error_code.hpp"

namespace rcand::kernel::r2r {

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
  nlohmann::json payload{{"code", static_cast<int>(code)}, {"message", std::move(message)}};
  if (ref) payload["ref"] = *ref;
  return payload;
}

}  // namespace rcand::kernel::r2r
