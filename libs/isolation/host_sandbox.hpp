// What an isolated capability's host process may do (issue 34): less than rcand. Entered by rcand-plugin-host before
// it opens the plugin, so the plugin's own initialisation already runs inside it:
//   - no new privileges (setuid binaries gain nothing) and no Linux capabilities, the bounding set emptied as far as
//     the process may;
//   - a seccomp filter (libseccomp) refusing with EPERM what no capability needs: tracing or reading other processes'
//     memory, signalling rcand or any process group, kernel modules, mounts and namespaces, reboot, BPF, keyrings,
//     clock setting and raw I/O ports; and, unless its manifest entry says it needs the network
//     ("isolation_needs": ["network"]), sockets other than Unix ones;
//   - a Landlock ruleset (file_access.hpp): rcand's own files and /proc/<rcand> hidden, and in /dev only the
//     ordinary entries and the device classes it needs ("video", "serial").
// EPERM rather than a kill: a library that probes for a feature gets "not permitted" and goes on without it.
#pragma once

#include <sys/types.h>

#include <nlohmann/json.hpp>

namespace rcand::isolation {

// The calling process from now on (before it starts any thread other than its own: the Landlock ruleset binds the
// calling thread and those it starts afterwards; the seccomp filter every thread). `parent` is rcand's pid, `order`
// the start message's "sandbox": {"network": bool, "video": bool, "serial": bool, "hidden": [paths]} (what is left
// out is not granted). Answers what it enforces on files (restrict_files()), for the capability's status. Throws
// std::runtime_error naming the step that failed (the host then refuses to start the capability).
nlohmann::json enter_host_sandbox(pid_t parent, const nlohmann::json& order);

}  // namespace rcand::isolation
