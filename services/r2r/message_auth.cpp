#include "services/r2r/message_auth.hpp"

#include <openssl/bio.h>
#include <openssl/evp.h>
#include <openssl/pem.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "libs/rcan/base64.hpp"
#include "libs/rcan/role_scopes.hpp"

namespace rcand::kernel::r2r {
namespace {

using nlohmann::json;

constexpr std::size_t kEd25519KeyBytes = 32;
constexpr std::size_t kEd25519SigBytes = 64;

EVP_PKEY* as_pkey(void* p) { return static_cast<EVP_PKEY*>(p); }

struct BioDeleter {
  void operator()(BIO* bio) const noexcept { BIO_free(bio); }
};
using BioPtr = std::unique_ptr<BIO, BioDeleter>;
struct MdCtxDeleter {
  void operator()(EVP_MD_CTX* ctx) const noexcept { EVP_MD_CTX_free(ctx); }
};
using MdCtxPtr = std::unique_ptr<EVP_MD_CTX, MdCtxDeleter>;

std::string read_text_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::invalid_argument("cannot read key file " + file.string());
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::string trim(std::string_view text) {
  const auto begin = text.find_first_not_of(" \t\r\n");
  if (begin == std::string_view::npos) return {};
  const auto end = text.find_last_not_of(" \t\r\n");
  return std::string(text.substr(begin, end - begin + 1));
}

EVP_PKEY* load_key(std::string_view text, bool want_private) {
  const std::string trimmed = trim(text);
  EVP_PKEY* pkey = nullptr;
  if (trimmed.rfind("-----BEGIN", 0) == 0) {
    BioPtr bio(BIO_new_mem_buf(trimmed.data(), static_cast<int>(trimmed.size())));
    if (!bio) throw std::runtime_error("out of memory reading a key");
    pkey = want_private ? PEM_read_bio_PrivateKey(bio.get(), nullptr, nullptr, nullptr)
                        : PEM_read_bio_PUBKEY(bio.get(), nullptr, nullptr, nullptr);
    if (pkey == nullptr)
      throw std::invalid_argument(want_private ? "not a PEM private key (expected -----BEGIN PRIVATE KEY-----)"
                                               : "not a PEM public key (expected -----BEGIN PUBLIC KEY-----)");
    if (EVP_PKEY_id(pkey) != EVP_PKEY_ED25519) {
      EVP_PKEY_free(pkey);
      throw std::invalid_argument("the PEM key is not an Ed25519 key");
    }
    return pkey;
  }
  const auto raw = base64_decode(trimmed);
  if (!raw || raw->size() != kEd25519KeyBytes)
    throw std::invalid_argument("expected a PEM Ed25519 key or 32 raw key bytes in base64");
  const auto* bytes = reinterpret_cast<const unsigned char*>(raw->data());
  pkey = want_private ? EVP_PKEY_new_raw_private_key(EVP_PKEY_ED25519, nullptr, bytes, raw->size())
                      : EVP_PKEY_new_raw_public_key(EVP_PKEY_ED25519, nullptr, bytes, raw->size());
  if (pkey == nullptr) throw std::invalid_argument("OpenSSL refused the raw Ed25519 key");
  return pkey;
}

std::string bio_text(BIO* bio) {
  char* data = nullptr;
  const long n = BIO_get_mem_data(bio, &data);
  return std::string(data, static_cast<std::size_t>(n));
}

}  // namespace

Ed25519Key::Ed25519Key(void* pkey, bool is_private) noexcept : pkey_(pkey), private_(is_private) {}
Ed25519Key::Ed25519Key(Ed25519Key&& other) noexcept : pkey_(std::exchange(other.pkey_, nullptr)), private_(other.private_) {}
Ed25519Key& Ed25519Key::operator=(Ed25519Key&& other) noexcept {
  if (this != &other) {
    EVP_PKEY_free(as_pkey(pkey_));
    pkey_ = std::exchange(other.pkey_, nullptr);
    private_ = other.private_;
  }
  return *this;
}
Ed25519Key::~Ed25519Key() { EVP_PKEY_free(as_pkey(pkey_)); }

Ed25519Key Ed25519Key::public_from_text(std::string_view text) { return Ed25519Key(load_key(text, false), false); }
Ed25519Key Ed25519Key::private_from_text(std::string_view text) { return Ed25519Key(load_key(text, true), true); }
Ed25519Key Ed25519Key::public_from_file(const std::filesystem::path& file) { return public_from_text(read_text_file(file)); }
Ed25519Key Ed25519Key::private_from_file(const std::filesystem::path& file) { return private_from_text(read_text_file(file)); }

Ed25519Key Ed25519Key::generate() {
  EVP_PKEY* pkey = nullptr;
  EVP_PKEY_CTX* ctx = EVP_PKEY_CTX_new_id(EVP_PKEY_ED25519, nullptr);
  const bool ok = ctx != nullptr && EVP_PKEY_keygen_init(ctx) == 1 && EVP_PKEY_keygen(ctx, &pkey) == 1;
  EVP_PKEY_CTX_free(ctx);
  if (!ok) throw std::runtime_error("Ed25519 key generation failed");
  return Ed25519Key(pkey, true);
}

std::string Ed25519Key::sign(std::string_view data) const {
  if (!private_) throw std::logic_error("cannot sign with a public key");
  MdCtxPtr ctx(EVP_MD_CTX_new());
  std::string signature(kEd25519SigBytes, '\0');
  std::size_t length = signature.size();
  if (!ctx || EVP_DigestSignInit(ctx.get(), nullptr, nullptr, nullptr, as_pkey(pkey_)) != 1 ||
      EVP_DigestSign(ctx.get(), reinterpret_cast<unsigned char*>(signature.data()), &length,
                     reinterpret_cast<const unsigned char*>(data.data()), data.size()) != 1)
    throw std::runtime_error("Ed25519 signing failed");
  signature.resize(length);
  return signature;
}

bool Ed25519Key::verify(std::string_view data, std::string_view signature) const noexcept {
  if (pkey_ == nullptr || signature.size() != kEd25519SigBytes) return false;
  MdCtxPtr ctx(EVP_MD_CTX_new());
  return ctx && EVP_DigestVerifyInit(ctx.get(), nullptr, nullptr, nullptr, as_pkey(pkey_)) == 1 &&
         EVP_DigestVerify(ctx.get(), reinterpret_cast<const unsigned char*>(signature.data()), signature.size(),
                          reinterpret_cast<const unsigned char*>(data.data()), data.size()) == 1;
}

std::string Ed25519Key::public_base64() const {
  std::string raw(kEd25519KeyBytes, '\0');
  std::size_t length = raw.size();
  if (EVP_PKEY_get_raw_public_key(as_pkey(pkey_), reinterpret_cast<unsigned char*>(raw.data()), &length) != 1)
    throw std::runtime_error("cannot read the Ed25519 public key");
  raw.resize(length);
  return base64_encode(raw);
}

std::string Ed25519Key::public_pem() const {
  BioPtr bio(BIO_new(BIO_s_mem()));
  if (!bio || PEM_write_bio_PUBKEY(bio.get(), as_pkey(pkey_)) != 1) throw std::runtime_error("cannot write the public key");
  return bio_text(bio.get());
}

std::string Ed25519Key::private_pem() const {
  if (!private_) throw std::logic_error("not a private key");
  BioPtr bio(BIO_new(BIO_s_mem()));
  if (!bio || PEM_write_bio_PrivateKey(bio.get(), as_pkey(pkey_), nullptr, nullptr, 0, nullptr, nullptr) != 1)
    throw std::runtime_error("cannot write the private key");
  return bio_text(bio.get());
}

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

sdk::Scope required_scope(MessageType type) noexcept {
  switch (type) {
    case MessageType::Status:
    case MessageType::Error: return sdk::Scope::Status;
    default: return sdk::Scope::Control;
  }
}

MessageAuthenticator::MessageAuthenticator(const Authenticator& tokens, MessageAuthSettings settings)
    : tokens_(tokens), settings_(std::move(settings)), peers_(std::make_shared<const std::vector<PeerKey>>(settings_.peers)) {}

void MessageAuthenticator::replace_peers(std::vector<PeerKey> peers) {
  auto table = std::make_shared<const std::vector<PeerKey>>(std::move(peers));
  std::lock_guard lock(peers_mutex_);
  peers_.swap(table);
}

std::shared_ptr<const std::vector<PeerKey>> MessageAuthenticator::current_peers() const {
  std::lock_guard lock(peers_mutex_);
  return peers_;
}

std::size_t MessageAuthenticator::peer_count() const { return current_peers()->size(); }

std::variant<Principal, AuthFailure> MessageAuthenticator::authorize(const Envelope& envelope, const json& raw,
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

std::variant<Principal, AuthFailure> MessageAuthenticator::verify_signature(const Envelope& envelope, const json& raw,
                                                                            double now_s) const {
  const json& signature = envelope.header_extra["signature"];
  if (!signature.is_object() || !signature.contains("key_id") || !signature["key_id"].is_string() || !signature.contains("sig") ||
      !signature["sig"].is_string())
    return AuthFailure{"header.signature must be {\"key_id\": string, \"sig\": base64 string}"};
  const std::string& key_id = signature["key_id"].get_ref<const std::string&>();
  const auto table = current_peers();
  const auto peer =
      std::find_if(table->begin(), table->end(), [&](const PeerKey& candidate) { return candidate.name == key_id; });
  if (peer == table->end() || !peer->key) return AuthFailure{"unknown signing key '" + key_id + "'"};
  const auto sig = base64_decode(signature["sig"].get_ref<const std::string&>());
  if (!sig || !peer->key->verify(signing_input(raw), *sig)) return AuthFailure{"bad signature for key '" + key_id + "'"};
  // Checked only after the signature holds, so the timestamp is the sender's own.
  if (envelope.source_id != peer->name)
    return AuthFailure{"key '" + key_id + "' cannot sign for source_id '" + envelope.source_id + "'"};
  if (envelope.timestamp < now_s - settings_.replay_window_s)
    return AuthFailure{"stale message: timestamp is more than " + json(settings_.replay_window_s).dump() + " s old"};
  if (envelope.timestamp > now_s + settings_.future_skew_s)
    return AuthFailure{"timestamp is more than " + json(settings_.future_skew_s).dump() + " s in the future"};
  return Principal{peer->name, peer->role, default_scopes(peer->role), "signature"};
}

}  // namespace rcand::kernel::r2r
