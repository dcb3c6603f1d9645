// Whether another user (the service's `rcand`) could open a path, judged as root checks from its mode bits, owner
// and group: for `rcand --check-config --as-user rcand`, run by an admin who may read everything herself.
#pragma once

#include <sys/types.h>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace rcand {

struct UserIdentity {
  std::string name;
  uid_t uid = 0;
  gid_t gid = 0;
  std::vector<gid_t> groups;  // every group the user is in, the primary one included
};

// The user's ids and groups from the system's user database; nullopt when there is no such user.
std::optional<UserIdentity> lookup_user(const std::string& name);

enum class Access { Read, Write, ReadWrite, Search };

// Empty when `user` may access `path` as `access` asks (every directory on the way must be searchable); else why
// not, e.g. "/var/lib/rcand: not writable by rcand (owner root, group root, mode 0755)". For Write, a path that does
// not exist yet (a state directory or an audit file rcand creates) is judged by its nearest existing parent, which
// must then be writable; for the others a missing path is a problem ("/dev/ttyUSB0: does not exist").
std::string access_problem(const UserIdentity& user, const std::filesystem::path& path, Access access);

}  // namespace rcand
