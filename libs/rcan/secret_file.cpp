#include "libs/rcan/secret_file.hpp"

#include <fstream>
#include <iterator>

#include "libs/base/file_exposure.hpp"
#include "libs/rcan/crypto.hpp"

namespace rcand {
namespace {

// SHA-256 of config/dev-jwt.secret (without its newline): the secret README.md's examples sign tokens with.
constexpr std::string_view kDevelopmentSecretSha256 = "ae48e538c4146ada37a47ffc6f38889e8890935713cdfafc4cbf0d55526c0b56";

}  // namespace

SecretFile read_secret_file(const std::filesystem::path& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) return {std::nullopt, "secret file '" + path.string() + "' is a directory", {}};
  std::ifstream in(path, std::ios::binary);
  if (!in) return {std::nullopt, "cannot read secret file '" + path.string() + "'", {}};
  std::string secret{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  if (in.bad()) return {std::nullopt, "cannot read secret file '" + path.string() + "'", {}};
  // Editors and `echo` add a newline nobody means as part of the key.
  while (!secret.empty() && (secret.back() == '\n' || secret.back() == '\r')) secret.pop_back();
  if (secret.empty()) return {std::nullopt, "secret file '" + path.string() + "' is empty", {}};
  if (sha256_hex(secret) == kDevelopmentSecretSha256) return {std::move(secret), {}, {}, true};
  return {std::move(secret), {}, others_may_access(path, "this secret"), false};
}

}  // namespace rcand
