#include "libs/isolation/host_process.hpp"

#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <system_error>
#include <vector>

extern char** environ;

namespace rcand::isolation {

namespace {
constexpr int kChannelFd = 3, kRingFd = 4;  // where the host finds its end of the channel, and the frame ring
}

std::optional<std::filesystem::path> find_host_binary(const std::filesystem::path& installed_dir) {
  std::error_code ec;
  if (const char* env = std::getenv("RCAND_PLUGIN_HOST"); env != nullptr && *env != '\0')
    return std::filesystem::is_regular_file(env, ec) ? std::optional<std::filesystem::path>(env) : std::nullopt;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec && std::filesystem::is_regular_file(self.parent_path() / "rcand-plugin-host", ec))
    return self.parent_path() / "rcand-plugin-host";
  if (std::filesystem::is_regular_file(installed_dir / "rcand-plugin-host", ec)) return installed_dir / "rcand-plugin-host";
  return std::nullopt;
}

pid_t spawn_host(const std::filesystem::path& binary, int channel_fd, int ring_fd) {
  // dup2 onto 3 and 4 clears close-on-exec there; a descriptor already at 3 or 4 is moved away first, since dup2 onto
  // itself would leave the flag set, and the first dup2 could overwrite the second's source.
  const auto away = [](int fd, const char* what) {
    if (fd != kChannelFd && fd != kRingFd) return fd;
    const int moved = ::fcntl(fd, F_DUPFD_CLOEXEC, kRingFd + 1);
    if (moved < 0) throw std::system_error(errno, std::generic_category(), what);
    return moved;
  };
  const int channel = away(channel_fd, "dup of the channel");
  int ring = -1;
  try {
    ring = away(ring_fd, "dup of the frame ring");
  } catch (...) {
    if (channel != channel_fd) ::close(channel);
    throw;
  }
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, channel, kChannelFd);
  posix_spawn_file_actions_adddup2(&actions, ring, kRingFd);
  posix_spawn_file_actions_addclosefrom_np(&actions, kRingFd + 1);  // rcand's sockets and files stay rcand's
  const std::string parent = std::to_string(::getpid());
  const std::string path = binary.string();
  std::vector<char*> argv{const_cast<char*>(path.c_str()), const_cast<char*>("--parent"), const_cast<char*>(parent.c_str()),
                          nullptr};
  pid_t pid = 0;
  const int error = ::posix_spawn(&pid, path.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (channel != channel_fd) ::close(channel);
  if (ring != ring_fd) ::close(ring);
  if (error != 0) throw std::system_error(error, std::generic_category(), "cannot start " + path);
  return pid;
}

std::string reap(pid_t pid, std::chrono::milliseconds grace) {
  // A pidfd is readable once the process ended: the grace is waited on that event, not by polling waitpid.
  if (const int pidfd = static_cast<int>(::syscall(SYS_pidfd_open, pid, 0)); pidfd >= 0) {
    pollfd ended{pidfd, POLLIN, 0};
    if (::poll(&ended, 1, static_cast<int>(grace.count())) == 0) ::kill(pid, SIGKILL);
    ::close(pidfd);
  }
  int status = 0;
  pid_t got = 0;
  while ((got = ::waitpid(pid, &status, 0)) < 0 && errno == EINTR) {
  }
  if (got < 0) return "ended (its exit status is lost: " + std::string(std::strerror(errno)) + ")";
  if (WIFEXITED(status)) return "exited with status " + std::to_string(WEXITSTATUS(status));
  const int signal = WTERMSIG(status);
  const char* abbrev = ::sigabbrev_np(signal);
  return "was killed by signal " + std::to_string(signal) + (abbrev != nullptr ? " (SIG" + std::string(abbrev) + ")" : "");
}

std::optional<std::size_t> resident_bytes(pid_t pid) {
  std::ifstream statm("/proc/" + std::to_string(pid) + "/statm");
  std::size_t size = 0, resident = 0;
  if (!(statm >> size >> resident)) return std::nullopt;
  return resident * static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
}

}  // namespace rcand::isolation
