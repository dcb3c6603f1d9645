// A fresh private directory under the temp dir (mkdtemp), removed with everything in it at scope exit.
#pragma once

#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

namespace rcand::test {

class TempDir {
 public:
  explicit TempDir(const std::string& prefix = "rcand-test") {
    std::string pattern = (std::filesystem::temp_directory_path() / (prefix + "-XXXXXX")).string();
    if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed for " + pattern);
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const noexcept { return path_; }
  static void safe_mode(const std::filesystem::path& path) {
    std::filesystem::permissions(path, std::filesystem::perms::group_write | std::filesystem::perms::others_write,
                                 std::filesystem::perm_options::remove);
  }
  // Writes `content` to `relative` (subdirectories made as needed) in the directory; returns its path. Neither the
  // file nor a directory made for it is writable by group or others, whatever the umask: rcand refuses a config
  // another user could change (libs/base/file_trust.hpp), and a test's config must not be that by accident.
  std::filesystem::path write(const std::filesystem::path& relative, const std::string& content) const {
    const auto file = path_ / relative;
    if (!std::filesystem::exists(file.parent_path())) {
      std::filesystem::create_directories(file.parent_path());
      for (auto dir = file.parent_path(); dir != path_ && dir != dir.parent_path(); dir = dir.parent_path()) safe_mode(dir);
    }
    std::ofstream(file, std::ios::binary) << content;
    safe_mode(file);
    return file;
  }

 private:
  std::filesystem::path path_;
};

}  // namespace rcand::test
