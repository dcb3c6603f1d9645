#include "libs/r2r_wire/ed25519_key.hpp"

#include <openssl/bio.h>
#include <openssl/evp.h>
#include <openssl/pem.h>

#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "libs/rcan/base64.hpp"

namespace rcand::r2r_wire {
namespace {

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

}  // namespace rcand::r2r_wire
