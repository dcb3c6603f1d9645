// Reads a secret file (the JWT secret, R2R tokens) the same way everywhere (rcand and `rcanctl token issue`), so both
// sign with the same bytes.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

namespace rcand {

struct SecretFile {
  std::optional<std::string> secret;
  std::string error;         // names the file, never its contents
  std::string warning;       // set when other users may read it (libs/base/file_exposure.hpp): the caller logs it
  bool development = false;  // it is the repository's public development secret (config/dev-jwt.secret)
};

// The file's bytes with trailing "\n" / "\r\n" stripped; an unreadable or empty file is an error. A secret that
// other users can read is still used, with a warning. The repository's development secret is recognised by its
// digest and never warned about: it is public anyway, and git cannot keep the 0600 mode of a fresh clone's copy.
SecretFile read_secret_file(const std::filesystem::path& path);

}  // namespace rcand
