#include "libs/isolation/host_sandbox.hpp"

#include <linux/capability.h>
#include <seccomp.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <memory>
#include <stdexcept>

#include "libs/isolation/file_access.hpp"

namespace rcand::isolation {

namespace {

// LeakSanitizer stops the world with ptrace on the process's own threads: a sanitizer build of the host keeps ptrace.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kLeakChecked = true;
#elif defined(__has_feature)
constexpr bool kLeakChecked = __has_feature(address_sanitizer);
#else
constexpr bool kLeakChecked = false;
#endif

// System calls no capability has any business making.
// clang-format off
constexpr const char* kRefused[] = {
    kLeakChecked ? "" : "ptrace", "process_vm_readv", "process_vm_writev", "kcmp", "kexec_load", "kexec_file_load",
    "init_module", "finit_module", "delete_module", "mount", "umount2", "pivot_root", "chroot", "move_mount",
    "open_tree", "fsopen", "fsmount", "fsconfig", "fspick", "mount_setattr", "setns", "unshare", "swapon", "swapoff",
    "reboot", "bpf", "perf_event_open", "userfaultfd", "keyctl", "add_key", "request_key", "acct", "settimeofday",
    "clock_settime", "clock_adjtime", "adjtimex", "open_by_handle_at", "name_to_handle_at", "iopl", "ioperm",
    "quotactl", "syslog", "vhangup", "lookup_dcookie", "fanotify_init", "tkill"};
// clang-format on

void check(int result, const char* step) {
  if (result < 0) throw std::runtime_error(std::string("sandbox: ") + step + ": " + std::strerror(-result));
}

// Every capability out of the bounding set (where the process may) and out of its own sets. capset(2) only when there
// is something to drop: the packaged unit already starts rcand with none, and its filter refuses capset (@privileged).
void drop_capabilities() {
  for (int cap = 0; cap <= CAP_LAST_CAP; ++cap)
    ::prctl(PR_CAPBSET_DROP, cap, 0, 0, 0);  // EPERM without CAP_SETPCAP: none to drop
  __user_cap_header_struct header{_LINUX_CAPABILITY_VERSION_3, 0};
  __user_cap_data_struct held[_LINUX_CAPABILITY_U32S_3]{};
  if (::syscall(SYS_capget, &header, held) != 0)
    throw std::runtime_error(std::string("sandbox: reading capabilities: ") + std::strerror(errno));
  bool any = false;
  for (const auto& set : held) any = any || set.effective != 0 || set.permitted != 0 || set.inheritable != 0;
  const __user_cap_data_struct none[_LINUX_CAPABILITY_U32S_3]{};
  if (any && ::syscall(SYS_capset, &header, none) != 0)
    throw std::runtime_error(std::string("sandbox: dropping capabilities: ") + std::strerror(errno));
}

}  // namespace

nlohmann::json enter_host_sandbox(pid_t parent, const nlohmann::json& order) {
  const auto need = [&order](const char* what) { return order.is_object() && order.value(what, false); };
  if (::prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0) != 0)
    throw std::runtime_error(std::string("sandbox: no_new_privs: ") + std::strerror(errno));
  drop_capabilities();
  FileNeeds files{need("video"), need("serial"), {"/proc/" + std::to_string(parent)}};
  if (order.is_object() && order.contains("hidden"))
    for (const auto& path : order.at("hidden")) files.hidden.emplace_back(path.get<std::string>());
  auto enforced = restrict_files(files);

  const std::unique_ptr<void, void (*)(scmp_filter_ctx)> filter(seccomp_init(SCMP_ACT_ALLOW), seccomp_release);
  if (!filter) throw std::runtime_error("sandbox: seccomp_init failed");
  check(seccomp_attr_set(filter.get(), SCMP_FLTATR_CTL_TSYNC, 1), "every thread");
  const auto refuse = [&](int syscall, unsigned count, const scmp_arg_cmp* args, const char* what) {
    check(seccomp_rule_add_array(filter.get(), SCMP_ACT_ERRNO(EPERM), syscall, count, args), what);
  };
  for (const char* name : kRefused) {
    if (*name == '\0') continue;
    const int syscall = seccomp_syscall_resolve_name(name);
    if (syscall != __NR_SCMP_ERROR) refuse(syscall, 0, nullptr, name);  // not every architecture has every call
  }
  // rcand itself, and every process group (rcand's included), are out of reach of its signals.
  // A negative pid (a group; -1, every process) has bit 31 set whether the kernel sees it sign-extended or not.
  // libseccomp's own order: datum_a is the value, or for SCMP_CMP_MASKED_EQ the mask and datum_b the value.
  const auto first_argument = [](scmp_compare op, scmp_datum_t a, scmp_datum_t b = 0) { return scmp_arg_cmp{0, op, a, b}; };
  const scmp_arg_cmp to_rcand = first_argument(SCMP_CMP_EQ, static_cast<std::uint32_t>(parent)),
                     to_group = first_argument(SCMP_CMP_MASKED_EQ, 0x80000000u, 0x80000000u),
                     to_own_group = first_argument(SCMP_CMP_EQ, 0);
  for (const auto* target : {&to_rcand, &to_group, &to_own_group}) refuse(SCMP_SYS(kill), 1, target, "signals");
  for (const int call : {SCMP_SYS(tgkill), SCMP_SYS(rt_sigqueueinfo), SCMP_SYS(rt_tgsigqueueinfo), SCMP_SYS(pidfd_open)})
    refuse(call, 1, &to_rcand, "signals to rcand");
  if (!need("network"))
    for (const int family : {AF_INET, AF_INET6, AF_PACKET, AF_NETLINK}) {
      const scmp_arg_cmp domain = first_argument(SCMP_CMP_EQ, static_cast<scmp_datum_t>(family));
      refuse(SCMP_SYS(socket), 1, &domain, "sockets");
    }
  check(seccomp_load(filter.get()), "loading the filter");
  return enforced;
}

}  // namespace rcand::isolation
