#include "libs/r2r_wire/message_signature.hpp"

#include "libs/r2r_wire/envelope.hpp"
#include "libs/rcan/base64.hpp"

namespace rcand::r2r_wire {

using nlohmann::json;

std::string signing_input(const json& message) {
  json unsigned_copy = message;
  if (auto header = unsigned_copy.find("header"); header != unsigned_copy.end() && header->is_object()) {
    header->erase("signature");
    header->erase(kRelayMarker);  // added by a relaying robot after the sender signed
  }
  return unsigned_copy.dump(-1, ' ', false, json::error_handler_t::replace);
}

void sign_message(json& message, const std::string& key_id, const Ed25519Key& key) {
  const std::string signature = key.sign(signing_input(message));
  message["header"]["signature"] = {{"key_id", key_id}, {"sig", base64_encode(signature)}};
}

void add_token(json& message, const std::string& token) { message["header"]["auth"] = {{"token", token}}; }

}  // namespace rcand::r2r_wire
