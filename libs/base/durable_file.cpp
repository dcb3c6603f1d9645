#include "libs/base/durable_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

namespace rcand {

std::optional<std::string> read_whole_file(const std::filesystem::path& file) {
  std::error_code ec;
  if (!std::filesystem::exists(file, ec)) return std::nullopt;
  std::ifstream in(file, std::ios::binary);
  if (!in) return std::string();
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

bool fsync_directory(const std::filesystem::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return false;
  const bool ok = ::fsync(fd) == 0;
  ::close(fd);
  return ok;
}

std::string replace_file_durably(const std::filesystem::path& dir, const std::string& name, const std::string& text) {
  const std::filesystem::path final_path = dir / name;
  const std::filesystem::path temp = dir / (name + ".tmp");
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0640);
  if (fd < 0) return "cannot create " + temp.string() + ": " + std::strerror(errno);
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string error = std::strerror(errno);
      ::close(fd);
      ::unlink(temp.c_str());  // a full disk keeps no half-written copy
      return "cannot write " + temp.string() + ": " + error;
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) {
    const std::string error = std::strerror(errno);
    ::close(fd);
    return "cannot fsync " + temp.string() + ": " + error;
  }
  ::close(fd);
  if (::rename(temp.c_str(), final_path.c_str()) != 0)
    return "cannot rename to " + final_path.string() + ": " + std::strerror(errno);
  if (!fsync_directory(dir)) return "cannot fsync " + dir.string();
  return {};
}

}  // namespace rcand
