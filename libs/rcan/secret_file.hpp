// Reads a JWT secret file the same way everywhere (rcand and `rcanctl token issue`), so both sign with the same bytes.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

namespace rcand {

struct SecretFile {
  std::optional<std::string> secret;
  std::string error;  // names the file, never its contents
};

// The file's bytes with trailing "\n" / "\r\n" stripped; an unreadable or empty file is an error.
SecretFile read_secret_file(const std::filesystem::path& path);

}  // namespace rcand
