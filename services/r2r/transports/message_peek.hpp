// What a transport may learn from an R2R message without interpreting it: its `type`, `header.source_id` and
// whether it was relayed (WebSocket: to address a connection by the name its peer announces, never by a relayed
// sender's; UDP and MQTT: status goes best-effort, other types reliably). A streaming scan with no document built;
// anything odd just leaves the fields empty.
#pragma once

#include <string>
#include <string_view>

namespace rcand::services::r2r {

struct MessagePeek {
  std::string type;       // "" when absent or not a string
  std::string source_id;  // "" when absent or not a string
  bool relayed = false;   // header.relayed_by present: another robot's message passed on (not the sender's own)
};

MessagePeek peek_message(std::string_view bytes) noexcept;

}  // namespace rcand::services::r2r
