// Shared slots (libs/base/slot_table.hpp) and who counts against which cap (kernel/auth/slots.hpp): a principal's cap,
// an address's cap over many principals, the reserved slots, auth mode open, and the refusal bodies.
#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include <vector>

#include "kernel/auth/slots.hpp"
#include "libs/base/slot_table.hpp"

using rcand::SlotHolder;
using rcand::SlotLimits;
using rcand::SlotTable;
using rcand::kernel::slot_holder;
using rcand::sdk::Role;

TEST_CASE("slots: a principal's cap, an address's cap over many principals, and the owners' reserved slots") {
  SlotTable table(SlotLimits{8, 2, 3, 4});
  std::vector<std::shared_ptr<void>> held;
  auto take = [&](const SlotHolder& holder) {
    auto claim = table.claim(holder);
    if (claim.slot) held.push_back(claim.slot);
    return claim;
  };
  const auto guest = slot_holder("guest", Role::Guest, false, "10.0.0.1");
  for (int i = 0; i < 3; ++i) REQUIRE(take(guest).slot);
  auto refused = take(guest);
  CHECK(refused.refusal == SlotTable::Refusal::PrincipalCap);
  CHECK(refused.held == 3);
  // Another principal on the same host: the address holds 4 at most, whoever asks.
  REQUIRE(take(slot_holder("user", Role::User, false, "10.0.0.1")).slot);
  refused = take(slot_holder("other-guest", Role::Guest, false, "10.0.0.1"));
  CHECK(refused.refusal == SlotTable::Refusal::AddressCap);
  CHECK(refused.held == 4);
  // Other hosts fill up to capacity - reserved; then only OWNER and CREATOR get in.
  REQUIRE(take(slot_holder("a", Role::Guest, false, "10.0.0.2")).slot);
  REQUIRE(take(slot_holder("b", Role::User, false, "10.0.0.3")).slot);
  CHECK(take(slot_holder("c", Role::Leasee, false, "10.0.0.4")).refusal == SlotTable::Refusal::Reserved);
  const auto owner = slot_holder("owner", Role::Owner, false, "10.0.0.1");  // neither cap counts it
  CHECK(owner.principal.empty());
  CHECK(owner.address.empty());
  REQUIRE(take(owner).slot);
  REQUIRE(take(slot_holder("creator", Role::Creator, false, "10.0.0.1")).slot);
  CHECK(table.in_use() == 8);
  CHECK(take(owner).refusal == SlotTable::Refusal::Full);
  // Slots come back when their last handle goes.
  held.erase(held.begin());
  CHECK(table.in_use() == 7);
  CHECK(take(guest).refusal == SlotTable::Refusal::Reserved);  // the guest's cap has room again, the table not
  held.clear();
  CHECK(table.in_use() == 0);
  CHECK(take(guest).slot);
}

TEST_CASE("slots: in auth mode open only the per-address cap applies, to everyone, and nothing is reserved") {
  SlotTable table(SlotLimits{4, 2, 1, 2});
  const auto local = slot_holder("open", Role::Creator, true, "127.0.0.1");
  CHECK(local.principal.empty());
  CHECK(local.may_use_reserved);
  auto a = table.claim(local), b = table.claim(local);
  REQUIRE(a.slot);
  REQUIRE(b.slot);  // one principal for everyone: its cap would be a cap on the robot
  CHECK(table.claim(local).refusal == SlotTable::Refusal::AddressCap);
  auto c = table.claim(slot_holder("open", Role::Creator, true, "::1"));
  auto d = table.claim(slot_holder("open", Role::Creator, true, "::1"));
  CHECK(c.slot);
  CHECK(d.slot);  // the reserved two as well
}

TEST_CASE("slots: each refusal answers with the error shape, the setting to change and Retry-After") {
  constexpr rcand::kernel::SlotWords words{"things", "x.max", "x.per_principal", "x.per_address", "x.reserved"};
  const auto guest = slot_holder("guest-principal", Role::Guest, false, "10.0.0.1");
  auto body_of = [&](SlotTable::Refusal refusal, int* status) {
    SlotTable::Claim claim;
    claim.refusal = refusal;
    claim.held = 3;
    const auto response = rcand::kernel::slot_refusal(claim, words, guest, Role::Guest);
    *status = response.status;
    CHECK(response.headers.size() == 1);
    CHECK(response.headers.front().first == "Retry-After");
    return nlohmann::json::parse(response.body);
  };
  int status = 0;
  auto body = body_of(SlotTable::Refusal::PrincipalCap, &status);
  CHECK(status == 429);
  CHECK(body["code"] == "TOO_MANY_CONNECTIONS");
  CHECK(body["error"].get<std::string>().find(
            "'guest-principal' already holds 3 things, the most a GUEST may (x.per_principal)") != std::string::npos);
  body = body_of(SlotTable::Refusal::AddressCap, &status);
  CHECK(status == 429);
  CHECK(body["error"].get<std::string>().find("address 10.0.0.1 already holds 3 things") != std::string::npos);
  body = body_of(SlotTable::Refusal::Reserved, &status);
  CHECK(status == 503);
  CHECK(body["code"] == "SLOTS_RESERVED");
  body = body_of(SlotTable::Refusal::Full, &status);
  CHECK(status == 503);
  CHECK(body["code"] == "UNAVAILABLE");
  CHECK(body["status"] == 503);
}
