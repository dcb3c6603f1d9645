// libFuzzer target: R2R messages as they land (parse_envelope on the raw bytes). Invariants: an accepted envelope
// has a source and a finite, non-negative timestamp, and re-serializes to bytes that parse again to the same
// header, type and payload; a refusal carries an R2R error code (100..105) and a message.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>
#include <variant>

#include "fuzz_check.hpp"
#include "libs/r2r_wire/envelope.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace rcand::r2r_wire;
  const auto parsed = parse_envelope(std::string_view(reinterpret_cast<const char*>(data), size));
  if (const auto* envelope = std::get_if<Envelope>(&parsed)) {
    RCAND_FUZZ_CHECK(!envelope->source_id.empty(), "an envelope has a source");
    RCAND_FUZZ_CHECK(std::isfinite(envelope->timestamp) && envelope->timestamp >= 0, "a timestamp is finite, >= 0");
    const auto again = parse_envelope(serialize(*envelope));
    const auto* round_trip = std::get_if<Envelope>(&again);
    RCAND_FUZZ_CHECK(round_trip != nullptr, "a serialized envelope parses again");
    RCAND_FUZZ_CHECK(round_trip->source_id == envelope->source_id && round_trip->target_id == envelope->target_id &&
                         round_trip->type == envelope->type && round_trip->payload == envelope->payload,
                     "a serialized envelope parses to the same message");
  } else {
    const auto& error = std::get<R2rError>(parsed);
    const int code = static_cast<int>(error.code);
    RCAND_FUZZ_CHECK(code >= 100 && code <= 105, "a refusal carries an R2R error code");
    RCAND_FUZZ_CHECK(!error.message.empty(), "a refusal explains itself");
  }
  return 0;
}
