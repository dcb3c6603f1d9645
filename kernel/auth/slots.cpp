#include "kernel/auth/slots.hpp"

#include "kernel/api/answers.hpp"
#include "libs/base/bounded_text.hpp"

namespace rcand::kernel {

SlotHolder slot_holder(std::string principal, sdk::Role role, bool open_mode, std::string address) {
  if (open_mode) return {{}, std::move(address), true};
  if (sdk::role_grants(role, sdk::Scope::Config)) return {{}, {}, true};
  return {std::move(principal), std::move(address), false};
}

http::Response slot_refusal(const SlotTable::Claim& claim, const SlotWords& words, const SlotHolder& holder, sdk::Role role) {
  const std::string what(words.what), held = std::to_string(claim.held);
  http::Response response;
  switch (claim.refusal.value_or(SlotTable::Refusal::Full)) {
    case SlotTable::Refusal::Full:
      response = error_response(503, "UNAVAILABLE", "too many " + what + " (" + std::string(words.capacity_key) + ")");
      break;
    case SlotTable::Refusal::PrincipalCap:
      response = error_response(429, words.cap_code,
                                "principal '" + bounded_text(holder.principal, 64) + "' already holds " + held + " " + what +
                                    ", the most a " + std::string(sdk::role_name(role)) + " may (" +
                                    std::string(words.principal_key) + "); close one first");
      break;
    case SlotTable::Refusal::AddressCap:
      response = error_response(429, words.cap_code,
                                "address " + holder.address + " already holds " + held + " " + what +
                                    ", the most one address may for principals below OWNER (for everyone in auth mode open; " +
                                    std::string(words.address_key) + "); close one first");
      break;
    case SlotTable::Refusal::Reserved:
      response = error_response(
          503, words.reserved_code,
          "the remaining " + what + " are reserved for OWNER and CREATOR principals (" + std::string(words.reserved_key) + ")");
      break;
  }
  response.headers.emplace_back("Retry-After", "5");
  return response;
}

}  // namespace rcand::kernel
