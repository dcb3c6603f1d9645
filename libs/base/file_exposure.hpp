// Whether other users of the machine can get at a secret, with the command that fixes it: the TLS private key
// (refused, as ssh refuses), the JWT secret, R2R token files, the MQTT broker's password or token and the R2R
// signing key (warned about at start).
#pragma once

#include <filesystem>
#include <string>

namespace rcand {

// "" when no user other than the owner (and the file's group) may read or write `file`; else what is wrong and the
// chmod that fixes it, naming the file as `what` ("this private key"). A file that cannot be stat'ed says so.
std::string others_may_access(const std::filesystem::path& file, const std::string& what);

}  // namespace rcand
