// Starting and ending an isolated capability's host process (rcand-plugin-host), and what its end means in words.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>

namespace rcand::isolation {

// The host binary: $RCAND_PLUGIN_HOST when set (tests: the build tree's), else rcand-plugin-host beside the running
// executable, else the one installed in `installed_dir`. nullopt when none exists (a named fault for the capability).
std::optional<std::filesystem::path> find_host_binary(const std::filesystem::path& installed_dir);

// Starts `binary` with `channel_fd` as its descriptor 3, `ring_fd` (the frame ring) as 4, and none of rcand's others
// (0-2 are shared: its log lines reach rcand's journal), and rcand's pid, which it checks against its parent's (it
// dies with rcand: PR_SET_PDEATHSIG). Throws std::system_error.
pid_t spawn_host(const std::filesystem::path& binary, int channel_fd, int ring_fd);

// Waits for `pid` to end and says how: "exited with status 3", "was killed by signal 11 (SIGSEGV)". One still running
// after `grace` (it closed its channel and lives on) is killed first.
std::string reap(pid_t pid, std::chrono::milliseconds grace = std::chrono::milliseconds(1000));

// The resident memory of `pid` in bytes; nullopt when it cannot be read (the process is gone).
std::optional<std::size_t> resident_bytes(pid_t pid);

}  // namespace rcand::isolation
