// The R2R message envelope (seed 004 "Message Format"): header {version, timestamp, source_id, target_id?}, type,
// payload. parse_envelope is a pure function (no globals, no I/O) so a fuzzer can drive it directly.
#pragma once

#include <nlohmann/json.hpp>

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <variant>

#include "libs/r2r_wire/error_code.hpp"

namespace rcand::r2r_wire {

inline constexpr std::size_t kMaxMessageBytes = 64 * 1024;  // docs/protocol.md §11: larger is refused with code 100
inline constexpr int kMaxMessageDepth = 32;                 // JSON nesting; deeper is refused with code 100
inline constexpr std::size_t kMaxIdBytes = 256;             // source_id / target_id: longer is refused with code 100
inline constexpr std::string_view kProtocolVersion = "1.0";
// The rcand hop marker (docs/protocol.md §11.3): a robot that relays a message for another robot of its fleet adds
// header.relayed_by = its own name. A message carrying it is never relayed again, and it is left out of what a
// signature covers (signing_input), so the original sender's signature still verifies at the target.
inline constexpr const char* kRelayMarker = "relayed_by";

enum class MessageType { Status, TaskRequest, TaskResponse, Command, Negotiation, Error };

std::string_view type_name(MessageType type) noexcept;
std::optional<MessageType> parse_message_type(std::string_view name) noexcept;

struct Envelope {
  std::string version = std::string(kProtocolVersion);
  double timestamp = 0.0;  // Unix seconds (fractions allowed)
  std::string source_id;
  std::optional<std::string> target_id;  // absent: a broadcast
  MessageType type = MessageType::Status;
  nlohmann::json payload = nlohmann::json::object();
  // The header exactly as received (including extensions such as `auth` and `signature`), for `ref` and for
  // signature checks; serialize() writes it back merged under the typed fields. Empty for locally built messages.
  nlohmann::json header_extra = nlohmann::json::object();
  // The whole message as received (null for locally built ones): what a signature covers, unknown fields included.
  nlohmann::json received;
};

struct R2rError {
  ErrorCode code = ErrorCode::InvalidFormat;
  std::string message;
  std::string field;                     // JSON pointer of the fault ("/header/source_id"), empty when it is the whole message
  std::optional<nlohmann::json> ref;     // the received header when it was an object, for the error reply
  std::optional<std::string> type;       // the received "type" when it was a string (never answer an `error` with an error)
  std::optional<std::string> source_id;  // the received source_id when it was a non-empty string (where to answer)
};

// Strict: valid JSON object within size and depth limits; header an object with version (string), timestamp
// (finite number >= 0), source_id (non-empty string), target_id (non-empty string, optional); type a known
// type; payload an object valid for its type (payload_schema). Unknown fields anywhere are ignored.
std::variant<Envelope, R2rError> parse_envelope(std::string_view bytes);

// The header as JSON: header_extra with the typed fields written over it.
nlohmann::json header_json(const Envelope& envelope);
// The whole message as JSON / as bytes (compact). Never throws on invalid UTF-8 (replaced).
nlohmann::json to_json(const Envelope& envelope);
std::string serialize(const Envelope& envelope);

}  // namespace rcand::r2r_wire
