// An Ed25519 key for signing and verifying R2R messages (docs/protocol.md §11): OpenSSL EVP objects, loaded from PEM or
// raw base64, never logged or echoed in an error.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace rcand::r2r_wire {

// An Ed25519 key (public, or a private key that can also sign). Move-only; owns its EVP_PKEY.
class Ed25519Key {
 public:
  // PEM (PUBLIC KEY / PRIVATE KEY) text, or 32 raw key bytes in standard base64. Throws std::invalid_argument
  // saying what is wrong (never echoing the key).
  static Ed25519Key public_from_text(std::string_view pem_or_base64);
  static Ed25519Key private_from_text(std::string_view pem_or_base64);
  static Ed25519Key public_from_file(const std::filesystem::path& file);
  static Ed25519Key private_from_file(const std::filesystem::path& file);
  static Ed25519Key generate();  // a fresh private key (tests, `rcanctl r2r keygen`)

  Ed25519Key(Ed25519Key&&) noexcept;
  Ed25519Key& operator=(Ed25519Key&&) noexcept;
  ~Ed25519Key();

  bool is_private() const noexcept { return private_; }
  std::string sign(std::string_view data) const;  // 64-byte signature; throws std::logic_error on a public key
  bool verify(std::string_view data, std::string_view signature) const noexcept;
  std::string public_base64() const;  // 32 raw bytes, base64
  std::string public_pem() const;
  std::string private_pem() const;  // throws std::logic_error on a public key

 private:
  Ed25519Key(void* pkey, bool is_private) noexcept;
  void* pkey_ = nullptr;  // EVP_PKEY*
  bool private_ = false;
};

}  // namespace rcand::r2r_wire
