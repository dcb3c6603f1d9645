#include "proposal_guard.hpp"

#include <rcand/sdk/request_body.hpp>

#include <cmath>

namespace rcand::plugins::chat {
namespace {

using sdk::Json;

// The action with the secrets redacted from every string and object key, however deep.
Json redacted_json(const Json& value, const std::vector<std::string>& secrets) {
  if (value.is_string()) return redact_secrets(value.get<std::string>(), secrets);
  if (value.is_array()) {
    Json out = Json::array();
    for (const auto& item : value) out.push_back(redacted_json(item, secrets));
    return out;
  }
  if (value.is_object()) {
    Json out = Json::object();
    for (const auto& [key, item] : value.items()) out[redact_secrets(key, secrets)] = redacted_json(item, secrets);
    return out;
  }
  return value;
}

std::string guarded(std::string text, const std::vector<std::string>& secrets, std::size_t max_bytes) {
  return sdk::bounded_utf8(redact_secrets(std::move(text), secrets), max_bytes);
}

}  // namespace

std::string redact_secrets(std::string text, const std::vector<std::string>& secrets) {
  for (const auto& secret : secrets) {
    if (secret.empty()) continue;
    for (auto at = text.find(secret); at != std::string::npos; at = text.find(secret, at))
      text.replace(at, secret.size(), "[api key]");
  }
  return text;
}

sdk::Proposal guard_proposal(sdk::Proposal p, const std::vector<std::string>& secrets) {
  p.raw_text = guarded(std::move(p.raw_text), secrets, kMaxReplyBytes);
  p.reasoning = guarded(std::move(p.reasoning), secrets, kMaxReplyBytes);
  if (p.suggestions.size() > kMaxSuggestions) p.suggestions.resize(kMaxSuggestions);
  for (auto& s : p.suggestions) s = guarded(std::move(s), secrets, kMaxSuggestionBytes);
  p.brain = guarded(std::move(p.brain), secrets, kMaxNameBytes);
  p.model = guarded(std::move(p.model), secrets, kMaxNameBytes);
  if (p.error.empty() && p.confidence && !(std::isfinite(*p.confidence) && *p.confidence >= 0 && *p.confidence <= 1))
    p.error = "the brain's confidence is not a number in [0, 1]";
  if (p.error.empty() && !p.action.is_null()) {
    p.action = redacted_json(p.action, secrets);
    const auto bytes = p.action.dump(-1, ' ', false, Json::error_handler_t::replace).size();
    if (bytes > kMaxActionBytes)
      p.error = "the brain's action is " + std::to_string(bytes) + " bytes of JSON, over the limit of " +
                std::to_string(kMaxActionBytes);
  }
  p.error = guarded(std::move(p.error), secrets, kMaxErrorBytes);
  if (!p.error.empty()) {
    p.action = nullptr;  // a failed brain proposes nothing
    p.confidence.reset();
  }
  return p;
}

}  // namespace rcand::plugins::chat
