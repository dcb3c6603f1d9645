#include "libs/isolation/file_access.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <linux/landlock.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>

namespace rcand::isolation {

namespace {

// The rights handled: those that open, read, write and execute. Directory-only rights (listing) are granted on
// directories only; Landlock refuses them on a file's rule.
constexpr __u64 kFileRights = LANDLOCK_ACCESS_FS_EXECUTE | LANDLOCK_ACCESS_FS_WRITE_FILE | LANDLOCK_ACCESS_FS_READ_FILE;
constexpr __u64 kHandled = kFileRights | LANDLOCK_ACCESS_FS_READ_DIR;

constexpr std::array<std::string_view, 7> kOrdinary{"null", "zero", "full", "random", "urandom", "shm", "mqueue"};
// Cameras: V4L2 nodes, media controllers, their sub-devices, and the DMA heaps libcamera allocates from.
constexpr std::array<std::string_view, 4> kVideoPrefixes{"video", "media", "v4l", "dma_heap"};
// Serial ports (ttyS0, ttyUSB0, ttyACM0, ttyAMA0, ttyTHS1 ...: "tty" and a capital), their by-id links' directory,
// Bluetooth RFCOMM, and pseudo-terminals (a serial device's emulator). Consoles (tty1) and /dev/tty are not ports.
constexpr std::array<std::string_view, 4> kSerialPrefixes{"serial", "rfcomm", "pts", "ptmx"};

bool starts_with_any(std::string_view name, const auto& prefixes) {
  for (const auto prefix : prefixes)
    if (name.starts_with(prefix)) return true;
  return false;
}

bool is_serial_port(std::string_view name) {
  return (name.size() > 3 && name.starts_with("tty") && name[3] >= 'A' && name[3] <= 'Z') ||
         starts_with_any(name, kSerialPrefixes);
}

struct Descriptor {
  int fd;
  explicit Descriptor(int fd) : fd(fd) {}
  Descriptor(const Descriptor&) = delete;
  Descriptor& operator=(const Descriptor&) = delete;
  ~Descriptor() {
    if (fd >= 0) ::close(fd);
  }
};

[[noreturn]] void fail(const std::string& step) { throw std::runtime_error("sandbox: " + step + ": " + std::strerror(errno)); }

void add_rule(int ruleset, const std::string& path, __u64 rights) {
  const Descriptor beneath(::open(path.c_str(), O_PATH | O_CLOEXEC));
  if (beneath.fd < 0) return;  // not reachable by this user anyway
  landlock_path_beneath_attr rule{};
  rule.allowed_access = rights;
  rule.parent_fd = beneath.fd;
  if (::syscall(SYS_landlock_add_rule, ruleset, LANDLOCK_RULE_PATH_BENEATH, &rule, 0) != 0) fail("a rule for " + path);
}

struct Walk {
  int ruleset;
  const FileNeeds& needs;
  const std::set<std::string>& hidden;  // canonical paths

  // Grants every entry of `directory` whole, except those hidden or holding something hidden (walked into), and in
  // /dev those the needs do not name. Links are left to their targets; sockets and pipes are not opened through
  // these rights.
  void allow_all_but(const std::string& directory) const {
    const std::unique_ptr<DIR, int (*)(DIR*)> listing(::opendir(directory.c_str()), ::closedir);
    if (!listing) fail("listing " + directory);
    while (const dirent* entry = ::readdir(listing.get())) {
      const std::string_view name = entry->d_name;
      if (name == "." || name == "..") continue;
      const std::string path = (directory == "/" ? "" : directory) + "/" + std::string(name);
      if (hidden.count(path) != 0 || (directory == "/dev" && !device_allowed(name, needs))) continue;
      struct stat info {};
      if (::lstat(path.c_str(), &info) != 0) continue;  // gone since the listing
      const bool is_directory = S_ISDIR(info.st_mode);
      if (!is_directory && !S_ISREG(info.st_mode) && !S_ISCHR(info.st_mode) && !S_ISBLK(info.st_mode)) continue;
      if (is_directory && (path == "/dev" || holds_hidden(path))) allow_all_but(path);
      else add_rule(ruleset, path, is_directory ? kHandled : kFileRights);
    }
  }

  bool holds_hidden(const std::string& directory) const {
    const auto first = hidden.lower_bound(directory + "/");  // sorted: the first path under it, if any, comes here
    return first != hidden.end() && first->starts_with(directory + "/");
  }
};

}  // namespace

bool device_allowed(std::string_view name, const FileNeeds& needs) {
  for (const auto ordinary : kOrdinary)
    if (name == ordinary) return true;
  if (starts_with_any(name, kVideoPrefixes)) return needs.video;
  if (is_serial_port(name)) return needs.serial;
  return false;
}

nlohmann::json restrict_files(const FileNeeds& needs) {
  const long abi = ::syscall(SYS_landlock_create_ruleset, nullptr, 0, LANDLOCK_CREATE_RULESET_VERSION);
  if (abi < 0)
    return {{"devices", "unrestricted"}, {"reason", std::string("Landlock is not available: ") + std::strerror(errno)}};
  std::set<std::string> hidden;
  for (const auto& path : needs.hidden) {
    std::error_code ec;
    if (auto real = std::filesystem::canonical(path, ec); !ec && real != "/") hidden.insert(real.string());
  }
  landlock_ruleset_attr attributes{};
  attributes.handled_access_fs = kHandled;
  const Descriptor ruleset(static_cast<int>(::syscall(SYS_landlock_create_ruleset, &attributes, sizeof attributes, 0)));
  if (ruleset.fd < 0) fail("a Landlock ruleset");
  add_rule(ruleset.fd, "/", LANDLOCK_ACCESS_FS_READ_DIR);  // any directory may be listed
  Walk{ruleset.fd, needs, hidden}.allow_all_but("/");
  if (::syscall(SYS_landlock_restrict_self, ruleset.fd, 0) != 0) fail("entering the Landlock ruleset");
  nlohmann::json classes = nlohmann::json::array();
  if (needs.video) classes.push_back("video");
  if (needs.serial) classes.push_back("serial");
  return {{"devices", "restricted"},
          {"landlock_abi", abi},
          {"device_classes", classes},
          {"rcand_files_hidden", hidden.size()}};  // how many, not which: the status is for guests too
}

}  // namespace rcand::isolation
