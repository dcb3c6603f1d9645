// Which files and devices an isolated capability's process may open (issue 34), enforced by Landlock (Linux 5.13+):
// everything rcand's user may open, except
//   - rcand's own files: its config and conf.d fragments, its state dir, the audit log, the JWT secret, the TLS key,
//     the swarm file (peers' tokens), and /proc/<rcand> (its memory and environment): `hidden`, which rcand names;
//   - in /dev, all but the ordinary entries (null, zero, full, random, urandom, shm, mqueue) and the device classes
//     its manifest entry needs ("isolation_needs": "video", "serial"). Buses (GPIO, I2C, SPI), memory, input and
//     every other device belong to rcand's drivers.
// Directories may still be listed everywhere (names are not secrets). Landlock grants by hierarchy, so the
// directories on the way to something hidden (and /dev) are granted entry by entry as they are when the process
// starts: what appears there later (a camera plugged in, a new file in /etc) is seen by the next host process.
#pragma once

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string_view>
#include <vector>

namespace rcand::isolation {

struct FileNeeds {
  bool video = false;
  bool serial = false;
  std::vector<std::filesystem::path> hidden;  // absolute; one that does not exist is left out
};

// An entry of /dev, by its name: whether a process with `needs` may open it.
bool device_allowed(std::string_view name, const FileNeeds& needs);

// The calling thread and the threads it starts from now on (so: before any other thread exists), after
// no_new_privs. Answers what is enforced, for the capability's status: {"devices": "restricted", "landlock_abi": N,
// "device_classes": [...], "rcand_files_hidden": N} or, on a kernel without Landlock, {"devices": "unrestricted", "reason":
// "..."}. Throws std::runtime_error when Landlock is there and refuses.
nlohmann::json restrict_files(const FileNeeds& needs);

}  // namespace rcand::isolation
