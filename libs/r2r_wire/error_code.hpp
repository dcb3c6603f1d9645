// R2R error codes (seed 004 "Error Handling", docs/protocol.md §11) and the `error` message that carries them.
#pragma once

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <string_view>

namespace rcand::r2r_wire {

enum class ErrorCode : int {
  InvalidFormat = 100,   // malformed envelope or payload, unknown type, over 64 KiB
  UnknownTarget = 101,   // target_id is neither this robot nor absent, and cannot be forwarded
  TaskAssigned = 102,    // a second award for a task this robot already holds from another requester
  Unauthorized = 103,    // missing/bad token or signature, insufficient scope, stale timestamp
  NetworkTimeout = 104,  // an awarded winner went silent past bid_deadline + 2 s
  EstopActive = 105,     // rcand extension: a command refused by local safety, e-stop latched
};

// "invalid_format", "unknown_target", ... ; "unknown" for a code outside 100..105.
std::string_view error_code_name(int code) noexcept;

// The `error` payload (docs/protocol.md §11): {"code", "message", "ref"}; ref = the header of the message it answers (omitted
// when unknown, e.g. when the bytes were not JSON), as error_ref gives it; message bounded to kMaxErrorMessageBytes.
nlohmann::json make_error_payload(ErrorCode code, std::string message, const std::optional<nlohmann::json>& ref);

// What an error reply echoes of the header it answers (issue 13 #15): the seed's fields only (version, timestamp,
// source_id, target_id), strings bounded, never `auth`, `signature` or whatever else a sender packed in - a 60 KiB
// header echoed to every bad message pinned megabytes per client that does not read.
nlohmann::json error_ref(const nlohmann::json& header);
inline constexpr std::size_t kMaxErrorMessageBytes = 1024;

}  // namespace rcand::r2r_wire
