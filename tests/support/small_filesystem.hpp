// A real filesystem small enough to fill up: a tmpfs of `bytes` mounted on a directory of the test's own (root only),
// unmounted at scope exit. For what rcand does when its disk is full (ENOSPC), without a fault seam.
#pragma once

#include <sys/mount.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

namespace rcand::test {

class SmallFilesystem {
 public:
  // Mounts it on `dir` (created). Not root: mounted() is false and why_not() says so (the caller skips); as root a
  // refused mount is reported the same way, and the caller decides whether that fails the test.
  SmallFilesystem(std::filesystem::path dir, std::size_t bytes) : dir_(std::move(dir)) {
    std::error_code ec;
    std::filesystem::create_directories(dir_, ec);
    if (::geteuid() != 0) {
      why_not_ = "mounting a small tmpfs needs root";
      return;
    }
    const std::string options = "size=" + std::to_string(bytes) + ",mode=0755";
    if (::mount("rcand-test-small", dir_.c_str(), "tmpfs", MS_NOSUID | MS_NODEV, options.c_str()) != 0)
      why_not_ = std::string("cannot mount a tmpfs on ") + dir_.string() + ": " + std::strerror(errno);
    else mounted_ = true;
  }
  ~SmallFilesystem() {
    if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
  }
  SmallFilesystem(const SmallFilesystem&) = delete;
  SmallFilesystem& operator=(const SmallFilesystem&) = delete;

  bool mounted() const noexcept { return mounted_; }
  bool root() const noexcept { return ::geteuid() == 0; }
  const std::string& why_not() const noexcept { return why_not_; }
  const std::filesystem::path& path() const noexcept { return dir_; }

  // Writes a filler file until the filesystem refuses (ENOSPC); returns whether it is full now.
  bool fill() const {
    std::ofstream out(dir_ / "filler", std::ios::binary | std::ios::app);
    const std::string block(4096, 'x');
    for (int i = 0; i < 1 << 20 && out.write(block.data(), static_cast<std::streamsize>(block.size())) && out.flush();) ++i;
    std::ofstream probe(dir_ / "probe", std::ios::binary);
    const bool full = !(probe << block << std::flush);
    probe.close();
    std::error_code ec;
    std::filesystem::remove(dir_ / "probe", ec);
    return full;
  }
  // Room again.
  void unfill() const {
    std::error_code ec;
    std::filesystem::remove(dir_ / "filler", ec);
  }

 private:
  std::filesystem::path dir_;
  bool mounted_ = false;
  std::string why_not_;
};

}  // namespace rcand::test
