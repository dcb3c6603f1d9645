// Whether a file rcand acts on (its config, a conf.d fragment, the directories that hold them) could have been
// changed by a user rcand does not trust, judged as sshd's StrictModes judges ~/.ssh: the owner must be root or the
// user rcand runs as, and neither the group nor others may write - except a group whose only members are those users
// (a user private group, so the 0664 a umask of 002 gives stays usable, as Debian's sshd allows) and, where the
// caller says so, a sticky directory (others may add files to it but not replace ours).
#pragma once

#include <sys/stat.h>
#include <sys/types.h>

#include <filesystem>
#include <string>

namespace rcand {

// "" when only trusted users can change what `info` (a stat of `path`) describes; else what is wrong and the
// command that fixes it, e.g. "writable by every user (mode 0666); fix: chmod go-w '/etc/rcand/conf.d/50-x.yaml'".
// Trusted: root and `user`.
std::string untrusted_writers(const std::filesystem::path& path, const struct stat& info, uid_t user, bool sticky_ok = false);

// The same for `path` itself, stat'ed (symbolic links followed); a path that cannot be stat'ed says so.
std::string untrusted_writers(const std::filesystem::path& path, uid_t user, bool sticky_ok = false);

// Whether every member of group `gid` (by primary group or by the group's member list) is root or `user`, and it
// has at least one (a group nobody is in serves setgid programs, which may write as it).
bool group_only_trusted(gid_t gid, uid_t user);

}  // namespace rcand
