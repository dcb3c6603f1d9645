// What a transport may learn from an R2R message without interpreting it: its `type` and `header.source_id`
// (WebSocket: to address a connection by the name its peer announces; UDP and MQTT: status goes best-effort, other
// types reliably). A streaming scan with no document built; anything odd just leaves the fields empty.
#pragma once

#include <string>
#include <string_view>

namespace rcand::kernel::r2r {

struct MessagePeek {
  std::string type;       // "" when absent or not a string
  std::string source_id;  // "" when absent or not a string
};

MessagePeek peek_message(std::string_view bytes) noexcept;

}  // namespace rcand::kernel::r2r
