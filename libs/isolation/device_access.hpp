// Which files and devices an isolated capability's process may open (issue 34), enforced by Landlock (Linux 5.13+):
// opening, reading, writing and executing stay allowed everywhere outside /dev; in /dev only the ordinary entries
// (null, zero, full, random, urandom, shm, mqueue) and the device classes its manifest entry needs
// ("isolation_needs": "video", "serial"). Buses (GPIO, I2C, SPI), memory, input and every other device belong to
// rcand's drivers. Entered by rcand-plugin-host before it opens the plugin; what /dev holds at that moment is what
// the process may see (a camera plugged in later is seen after a restart of the process).
#pragma once

#include <nlohmann/json.hpp>

#include <string_view>

namespace rcand::isolation {

struct DeviceNeeds {
  bool video = false;
  bool serial = false;
};

// An entry of /dev, by its name: whether a process with `needs` may open it.
bool device_allowed(std::string_view name, const DeviceNeeds& needs);

// The calling process, every thread of it, from now on. Answers what is enforced, for the capability's status:
// {"devices": "restricted", "landlock_abi": N, "device_classes": [...]} or, on a kernel without Landlock,
// {"devices": "unrestricted", "reason": "..."}. Throws std::runtime_error when Landlock is there and refuses.
nlohmann::json restrict_devices(const DeviceNeeds& needs);

}  // namespace rcand::isolation
