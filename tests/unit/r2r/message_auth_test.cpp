#include <doctest/doctest.h>

#include "libs/r2r_wire/message_signature.hpp"
#include "libs/rcan/base64.hpp"
#include "libs/rcan/crypto.hpp"
#include "services/r2r/message_auth.hpp"
#include "services/r2r/replay_guard.hpp"

using namespace rcand;
using namespace rcand::kernel;
using namespace rcand::services::r2r;
using nlohmann::json;
using rcand::sdk::Role;
using rcand::sdk::Scope;

namespace {

constexpr double kNow = 1'700'000'000.0;
const std::string kUserToken = "user-token-for-r2r-0123456789";
const std::string kGuestToken = "guest-token-for-r2r-0123456789";

Authenticator token_auth() {
  AuthSettings s;
  s.tokens = {{"peer-user", Role::User, sha256_hex(kUserToken)}, {"peer-guest", Role::Guest, sha256_hex(kGuestToken)}};
  return Authenticator(s);
}

json message(const std::string& type, json payload, double timestamp = kNow, const std::string& source = "alex") {
  return {{"header", {{"version", "1.0"}, {"timestamp", timestamp}, {"source_id", source}}},
          {"type", type},
          {"payload", std::move(payload)}};
}
json command_message(double timestamp = kNow, const std::string& source = "alex") {
  return message("command", {{"type", "move"}, {"linear", 0.2}}, timestamp, source);
}

r2r_wire::Envelope parse(const json& m) {
  auto parsed = r2r_wire::parse_envelope(m.dump());
  REQUIRE(std::holds_alternative<r2r_wire::Envelope>(parsed));
  return std::get<r2r_wire::Envelope>(parsed);
}

struct Keys {
  std::shared_ptr<const r2r_wire::Ed25519Key> alex =
      std::make_shared<const r2r_wire::Ed25519Key>(r2r_wire::Ed25519Key::generate());
  std::shared_ptr<const r2r_wire::Ed25519Key> mallory =
      std::make_shared<const r2r_wire::Ed25519Key>(r2r_wire::Ed25519Key::generate());
};

MessageAuthSettings signed_settings(const Keys& keys, bool required) {
  MessageAuthSettings s;
  s.require_signatures = required;
  s.peers.push_back(
      {"alex", Role::User,
       std::make_shared<const r2r_wire::Ed25519Key>(r2r_wire::Ed25519Key::public_from_text(keys.alex->public_pem()))});
  return s;
}

std::variant<Principal, AuthFailure> check(const MessageAuthenticator& auth, const json& m,
                                           std::optional<Principal> transport = std::nullopt) {
  const r2r_wire::Envelope e = parse(m);
  return auth.authorize(e, e.received, transport, required_scope(e.type), kNow);
}

std::string failure(const std::variant<Principal, AuthFailure>& verdict) {
  REQUIRE(std::holds_alternative<AuthFailure>(verdict));
  return std::get<AuthFailure>(verdict).message;
}
Principal principal(const std::variant<Principal, AuthFailure>& verdict) {
  if (auto* f = std::get_if<AuthFailure>(&verdict)) FAIL("refused: ", f->message);
  return std::get<Principal>(verdict);
}

}  // namespace

TEST_CASE("Ed25519 keys: PEM and raw base64 load, sign and verify; bad keys are refused without echoing them") {
  const r2r_wire::Ed25519Key key = r2r_wire::Ed25519Key::generate();
  const std::string signature = key.sign("hello");
  CHECK(signature.size() == 64);
  const r2r_wire::Ed25519Key from_pem = r2r_wire::Ed25519Key::public_from_text(key.public_pem());
  const r2r_wire::Ed25519Key from_raw = r2r_wire::Ed25519Key::public_from_text(key.public_base64());
  CHECK(from_pem.verify("hello", signature));
  CHECK(from_raw.verify("hello", signature));
  CHECK_FALSE(from_raw.verify("hellO", signature));
  CHECK_FALSE(from_raw.is_private());
  CHECK_THROWS_AS(from_raw.sign("x"), std::logic_error);
  const r2r_wire::Ed25519Key reloaded = r2r_wire::Ed25519Key::private_from_text(key.private_pem());
  CHECK(from_pem.verify("x", reloaded.sign("x")));

  CHECK_THROWS_AS(r2r_wire::Ed25519Key::public_from_text("not a key"), std::invalid_argument);
  CHECK_THROWS_AS(r2r_wire::Ed25519Key::public_from_text(base64_encode(std::string(31, 'k'))), std::invalid_argument);
  try {
    r2r_wire::Ed25519Key::public_from_text("-----BEGIN PUBLIC KEY-----\nc2VjcmV0\n-----END PUBLIC KEY-----\n");
    FAIL("accepted a broken PEM");
  } catch (const std::invalid_argument& e) {
    CHECK(std::string(e.what()).find("c2VjcmV0") == std::string::npos);
  }
  CHECK(base64_decode("aGk=") == "hi");
  CHECK_FALSE(base64_decode("aGk"));
  CHECK_FALSE(base64_decode("aG k"));
}

TEST_CASE("signatures: good passes as the peer's role; unsigned-when-required, bad, unknown key and tampered fail") {
  const Keys keys;
  const Authenticator tokens = token_auth();
  const MessageAuthenticator auth(tokens, signed_settings(keys, /*required=*/true));

  json good = command_message();
  r2r_wire::sign_message(good, "alex", *keys.alex);
  const Principal who = principal(check(auth, good));
  CHECK(who.name == "alex");
  CHECK(who.role == Role::User);
  CHECK(who.via == "signature");

  CHECK(failure(check(auth, command_message())).find("requires signed") != std::string::npos);
  // Not even a valid token rescues an unsigned message when signatures are required.
  json tokened = command_message();
  r2r_wire::add_token(tokened, kUserToken);
  CHECK(failure(check(auth, tokened)).find("requires signed") != std::string::npos);

  json forged = command_message();
  r2r_wire::sign_message(forged, "alex", *keys.mallory);
  CHECK(failure(check(auth, forged)).find("bad signature") != std::string::npos);

  json unknown = command_message(kNow, "mallory");
  r2r_wire::sign_message(unknown, "mallory", *keys.mallory);
  CHECK(failure(check(auth, unknown)).find("unknown signing key") != std::string::npos);

  json tampered = command_message();
  r2r_wire::sign_message(tampered, "alex", *keys.alex);
  tampered["payload"]["linear"] = 1.0;
  CHECK(failure(check(auth, tampered)).find("bad signature") != std::string::npos);

  json added_field = command_message();
  r2r_wire::sign_message(added_field, "alex", *keys.alex);
  added_field["extension"] = "smuggled";  // unknown fields are covered by the signature too
  CHECK(failure(check(auth, added_field)).find("bad signature") != std::string::npos);

  json impersonation = command_message(kNow, "blake");
  r2r_wire::sign_message(impersonation, "alex", *keys.alex);
  CHECK(failure(check(auth, impersonation)).find("cannot sign for") != std::string::npos);

  json garbage = command_message();
  garbage["header"]["signature"] = {{"key_id", "alex"}, {"sig", "!!"}};
  CHECK(failure(check(auth, garbage)).find("bad signature") != std::string::npos);
  garbage["header"]["signature"] = "alex";
  CHECK(failure(check(auth, garbage)).find("header.signature must be") != std::string::npos);
}

TEST_CASE("the signature is over the canonical form: key order does not matter") {
  const Keys keys;
  const Authenticator tokens = token_auth();
  const MessageAuthenticator auth(tokens, signed_settings(keys, true));
  json good = command_message();
  r2r_wire::sign_message(good, "alex", *keys.alex);
  // Written by hand with another key order and spacing, as a non-nlohmann peer might.
  const std::string reordered = std::string("{ \"payload\": {\"linear\": 0.2, \"type\": \"move\"}, \"type\": \"command\", ") +
                                "\"header\": {\"signature\": " + good["header"]["signature"].dump() +
                                ", \"source_id\": \"alex\", \"timestamp\": " + json(kNow).dump() + ", \"version\": \"1.0\"} }";
  auto parsed = r2r_wire::parse_envelope(reordered);
  REQUIRE(std::holds_alternative<r2r_wire::Envelope>(parsed));
  const r2r_wire::Envelope& e = std::get<r2r_wire::Envelope>(parsed);
  CHECK(std::holds_alternative<Principal>(auth.authorize(e, e.received, std::nullopt, Scope::Control, kNow)));
}

TEST_CASE("replay: a signed message older than the window or too far ahead is refused") {
  const Keys keys;
  const Authenticator tokens = token_auth();
  const MessageAuthenticator auth(tokens, signed_settings(keys, false));
  json stale = command_message(kNow - kDefaultReplayWindowS - 1);
  r2r_wire::sign_message(stale, "alex", *keys.alex);
  CHECK(failure(check(auth, stale)).find("stale") != std::string::npos);
  json recent = command_message(kNow - kDefaultReplayWindowS + 1);
  r2r_wire::sign_message(recent, "alex", *keys.alex);
  principal(check(auth, recent));
  json future = command_message(kNow + kDefaultFutureSkewS + 1);
  r2r_wire::sign_message(future, "alex", *keys.alex);
  CHECK(failure(check(auth, future)).find("future") != std::string::npos);
}

TEST_CASE("tokens: a known token passes with its role's scopes; wrong token and guest commands are refused") {
  const Authenticator tokens = token_auth();
  const MessageAuthenticator auth(tokens, {});

  json good = command_message();
  r2r_wire::add_token(good, kUserToken);
  CHECK(principal(check(auth, good)).name == "peer-user");

  json wrong = command_message();
  r2r_wire::add_token(wrong, "not-a-token");
  CHECK(failure(check(auth, wrong)).find("unknown or invalid token") != std::string::npos);

  json guest_command = command_message();
  r2r_wire::add_token(guest_command, kGuestToken);
  CHECK(failure(check(auth, guest_command)).find("cannot use scope 'control'") != std::string::npos);

  json guest_status = message("status", {{"battery", 50}});
  r2r_wire::add_token(guest_status, kGuestToken);
  CHECK(principal(check(auth, guest_status)).role == Role::Guest);

  CHECK(failure(check(auth, command_message())).find("authentication required") != std::string::npos);
  json malformed = command_message();
  malformed["header"]["auth"] = "token";
  CHECK(failure(check(auth, malformed)).find("header.auth") != std::string::npos);
}

TEST_CASE("a transport-authenticated principal is used when the message carries no credentials, scopes checked") {
  const Authenticator tokens = token_auth();
  const MessageAuthenticator auth(tokens, {});
  const Principal user{"ws-user", Role::User, {Scope::Status, Scope::Control}, "token"};
  CHECK(principal(check(auth, command_message(), user)).name == "ws-user");
  const Principal guest{"ws-guest", Role::Guest, {Scope::Status}, "token"};
  CHECK(failure(check(auth, command_message(), guest)).find("lacks scope 'control'") != std::string::npos);
}

TEST_CASE("required scopes per type") {
  CHECK(required_scope(r2r_wire::MessageType::Status) == Scope::Status);
  CHECK(required_scope(r2r_wire::MessageType::Error) == Scope::Status);
  CHECK(required_scope(r2r_wire::MessageType::Command) == Scope::Control);
  CHECK(required_scope(r2r_wire::MessageType::TaskRequest) == Scope::Control);
  CHECK(required_scope(r2r_wire::MessageType::Negotiation) == Scope::Control);
  CHECK(required_scope(r2r_wire::MessageType::TaskResponse) == Scope::Control);
}

TEST_CASE("replay guard: a signature is accepted once inside its window, and memory stays bounded") {
  ReplayGuard guard(30.0, 100);
  CHECK(guard.first_time("sig-a", 0.0));
  CHECK_FALSE(guard.first_time("sig-a", 10.0));
  CHECK(guard.first_time("sig-b", 10.0));
  CHECK(guard.first_time("sig-a", 40.5));  // forgotten after the window (stale timestamps are refused anyway)
  for (int i = 0; i < 1000; ++i) guard.first_time("flood-" + std::to_string(i), 41.0 + i * 0.001);
  CHECK(guard.size() <= 100);
}
