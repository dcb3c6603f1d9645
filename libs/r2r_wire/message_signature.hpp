// Signing an R2R message (docs/protocol.md §11): header.signature {"key_id", "sig"} over the canonical message, and
// header.auth.token for a shared token.
#pragma once

#include <nlohmann/json.hpp>

#include <string>

#include "libs/r2r_wire/ed25519_key.hpp"

namespace rcand::r2r_wire {

// The bytes a signature covers: the message as JSON with header.signature and the hop marker (kRelayMarker) removed, dumped by
// nlohmann (keys sorted, compact) - canonical whatever order the sender wrote.
std::string signing_input(const nlohmann::json& message);
// Adds header.signature {"key_id", "sig" (standard base64)} to `message` (a whole message object).
void sign_message(nlohmann::json& message, const std::string& key_id, const Ed25519Key& key);
// Adds header.auth.token.
void add_token(nlohmann::json& message, const std::string& token);

}  // namespace rcand::r2r_wire
