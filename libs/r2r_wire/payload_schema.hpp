// Per-type payload validation (docs/protocol.md §11 payload rulings). Types are checked strictly; unknown fields ignored.
#pragma once

#include <nlohmann/json.hpp>

#include <optional>
#include <string>

#include "libs/r2r_wire/envelope.hpp"

namespace rcand::r2r_wire {

struct PayloadFault {
  std::string field;  // JSON pointer relative to the message ("/payload/task_id")
  std::string message;
};

// nullopt when `payload` (already known to be an object) is acceptable for `type`.
std::optional<PayloadFault> check_payload(MessageType type, const nlohmann::json& payload);

// A `command` payload {"type":"estop","reason"?}: the fleet e-stop (docs/protocol.md §11.15), scope `status`.
bool is_fleet_estop(MessageType type, const nlohmann::json& payload) noexcept;

}  // namespace rcand::r2r_wire
