#include "services/r2r/message_auth.hpp"

#include <algorithm>
#include <utility>

#include "libs/r2r_wire/message_signature.hpp"
#include "libs/rcan/base64.hpp"
#include "libs/rcan/role_scopes.hpp"

namespace rcand::services::r2r {

using namespace rcand::kernel;

using nlohmann::json;

sdk::Scope required_scope(r2r_wire::MessageType type) noexcept {
  switch (type) {
    case r2r_wire::MessageType::Status:
    case r2r_wire::MessageType::Error: return sdk::Scope::Status;
    default: return sdk::Scope::Control;
  }
}

MessageAuthenticator::MessageAuthenticator(const Authenticator& tokens, MessageAuthSettings settings)
    : tokens_(tokens),
      settings_(std::move(settings)),
      peers_(std::make_shared<const std::vector<r2r_wire::PeerKey>>(settings_.peers)) {}

void MessageAuthenticator::replace_peers(std::vector<r2r_wire::PeerKey> peers) {
  auto table = std::make_shared<const std::vector<r2r_wire::PeerKey>>(std::move(peers));
  std::lock_guard lock(peers_mutex_);
  peers_.swap(table);
}

std::shared_ptr<const std::vector<r2r_wire::PeerKey>> MessageAuthenticator::current_peers() const {
  std::lock_guard lock(peers_mutex_);
  return peers_;
}

std::size_t MessageAuthenticator::peer_count() const { return current_peers()->size(); }

std::variant<Principal, AuthFailure> MessageAuthenticator::authorize(const r2r_wire::Envelope& envelope, const json& raw,
                                                                     const std::optional<Principal>& transport_principal,
                                                                     sdk::Scope needed, double now_s) const {
  const json& header = envelope.header_extra;
  std::variant<Principal, AuthFailure> who = AuthFailure{};
  if (header.contains("signature")) {
    who = verify_signature(envelope, raw, now_s);
  } else if (settings_.require_signatures) {
    return AuthFailure{"this robot requires signed R2R messages (header.signature)"};
  } else if (const auto auth = header.find("auth"); auth != header.end()) {
    const auto token = auth->is_object() ? auth->find("token") : auth->end();
    if (!auth->is_object() || token == auth->end() || !token->is_string())
      return AuthFailure{"header.auth must be an object with a string token"};
    auto verdict = tokens_.authorize(token->get_ref<const std::string&>(), needed, static_cast<std::int64_t>(now_s));
    if (auto* failure = std::get_if<AuthError>(&verdict)) return AuthFailure{failure->message};
    return std::get<Principal>(verdict);
  } else if (transport_principal) {
    who = *transport_principal;
  } else {
    auto verdict = tokens_.authorize(std::nullopt, needed, static_cast<std::int64_t>(now_s));  // open mode passes
    if (std::holds_alternative<AuthError>(verdict))
      return AuthFailure{"authentication required: a token in header.auth.token or a signature"};
    return std::get<Principal>(verdict);
  }
  if (auto* failure = std::get_if<AuthFailure>(&who)) return *failure;
  const Principal& principal = std::get<Principal>(who);
  if (std::find(principal.scopes.begin(), principal.scopes.end(), needed) == principal.scopes.end())
    return AuthFailure{"principal '" + principal.name + "' (" + std::string(sdk::role_name(principal.role)) + ") lacks scope '" +
                       std::string(sdk::scope_name(needed)) + "' needed for a " + std::string(type_name(envelope.type)) +
                       " message"};
  return who;
}

std::variant<Principal, AuthFailure> MessageAuthenticator::verify_signature(const r2r_wire::Envelope& envelope, const json& raw,
                                                                            double now_s) const {
  const json& signature = envelope.header_extra["signature"];
  if (!signature.is_object() || !signature.contains("key_id") || !signature["key_id"].is_string() || !signature.contains("sig") ||
      !signature["sig"].is_string())
    return AuthFailure{"header.signature must be {\"key_id\": string, \"sig\": base64 string}"};
  const std::string& key_id = signature["key_id"].get_ref<const std::string&>();
  const auto table = current_peers();
  const auto peer =
      std::find_if(table->begin(), table->end(), [&](const r2r_wire::PeerKey& candidate) { return candidate.name == key_id; });
  if (peer == table->end() || !peer->key) return AuthFailure{"unknown signing key '" + key_id + "'"};
  const auto sig = base64_decode(signature["sig"].get_ref<const std::string&>());
  if (!sig || !peer->key->verify(r2r_wire::signing_input(raw), *sig))
    return AuthFailure{"bad signature for key '" + key_id + "'"};
  // Checked only after the signature holds, so the timestamp is the sender's own.
  if (envelope.source_id != peer->name)
    return AuthFailure{"key '" + key_id + "' cannot sign for source_id '" + envelope.source_id + "'"};
  if (envelope.timestamp < now_s - settings_.replay_window_s)
    return AuthFailure{"stale message: timestamp is more than " + json(settings_.replay_window_s).dump() + " s old"};
  if (envelope.timestamp > now_s + settings_.future_skew_s)
    return AuthFailure{"timestamp is more than " + json(settings_.future_skew_s).dump() + " s in the future"};
  return Principal{peer->name, peer->role, default_scopes(peer->role), "signature"};
}

}  // namespace rcand::services::r2r
