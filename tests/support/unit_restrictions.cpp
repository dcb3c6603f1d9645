// rcand-unit-restrictions PROGRAM [ARGS...]: runs PROGRAM with what the packaged unit (packaging/systemd/rcand.service)
// takes away that rcand-plugin-host meets when it sandboxes itself: no Linux capabilities (CapabilityBoundingSet=),
// no new privileges (NoNewPrivileges=yes), and capset(2) refused with EPERM (SystemCallFilter=~@privileged,
// SystemCallErrorNumber=EPERM). tests/integration/isolation_test.cpp starts rcand through it, so a host that could
// only sandbox itself with privileges a packaged robot does not have fails a test rather than a robot.
#include <linux/capability.h>
#include <seccomp.h>
#include <sys/prctl.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: rcand-unit-restrictions PROGRAM [ARGS...]\n");
    return 2;
  }
  for (int cap = 0; cap <= CAP_LAST_CAP; ++cap) ::prctl(PR_CAPBSET_DROP, cap, 0, 0, 0);
  __user_cap_header_struct header{_LINUX_CAPABILITY_VERSION_3, 0};
  const __user_cap_data_struct none[_LINUX_CAPABILITY_U32S_3]{};
  if (::syscall(SYS_capset, &header, none) != 0 || ::prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0) != 0) {
    std::perror("rcand-unit-restrictions: dropping privileges");
    return 1;
  }
  scmp_filter_ctx filter = seccomp_init(SCMP_ACT_ALLOW);
  if (filter == nullptr || seccomp_rule_add(filter, SCMP_ACT_ERRNO(EPERM), SCMP_SYS(capset), 0) != 0 ||
      seccomp_load(filter) != 0) {
    std::fprintf(stderr, "rcand-unit-restrictions: cannot load the filter\n");
    return 1;
  }
  seccomp_release(filter);
  ::execv(argv[1], argv + 1);
  std::fprintf(stderr, "rcand-unit-restrictions: cannot run %s: %s\n", argv[1], std::strerror(errno));
  return 127;
}
