// Reads a secret file (the JWT secret, R2R tokens) the same way everywhere (rcand and `rcanctl token issue`), so both
// sign with the same bytes.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

namespace rcand {

struct SecretFile {
  std::optional<std::string> secret;
  std::string error;    // names the file, never its contents
  std::string warning;  // set when other users may read it (libs/base/file_exposure.hpp): the caller logs it
};

// The file's bytes with trailing "\n" / "\r\n" stripped; an unreadable or empty file is an error. A secret that
// other users can read is still used (a development secret checked out of git has mode 644), with a warning.
SecretFile read_secret_file(const std::filesystem::path& path);

}  // namespace rcand
