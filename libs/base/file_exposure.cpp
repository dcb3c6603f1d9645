#include "libs/base/file_exposure.hpp"

#include <sys/stat.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace rcand {

std::string others_may_access(const std::filesystem::path& file, const std::string& what) {
  struct stat info {};
  if (::stat(file.c_str(), &info) != 0) return std::string("cannot read: ") + std::strerror(errno);
  if ((info.st_mode & S_IRWXO) == 0) return {};
  char mode[8];
  std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(info.st_mode & 07777));
  return "other users may read or write " + what + " (mode " + mode + "); chmod 600 '" + file.string() +
         "' (or 640 with a group rcand is in)";
}

}  // namespace rcand
