#include "libs/base/user_access.hpp"

#include <grp.h>
#include <pwd.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>

namespace rcand {
namespace {

namespace fs = std::filesystem;

// The rwx bits of `info` that apply to `user` (as the "other" bits: owner, else group, else other).
mode_t granted(const UserIdentity& user, const struct stat& info) {
  if (info.st_uid == user.uid) return (info.st_mode & S_IRWXU) >> 6;
  if (std::find(user.groups.begin(), user.groups.end(), info.st_gid) != user.groups.end()) return (info.st_mode & S_IRWXG) >> 3;
  return info.st_mode & S_IRWXO;
}

std::string owner_text(const struct stat& info) {
  const passwd* owner = ::getpwuid(info.st_uid);
  const group* group = ::getgrgid(info.st_gid);
  char mode[8];
  std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(info.st_mode & 07777));
  return "owner " + (owner ? std::string(owner->pw_name) : std::to_string(info.st_uid)) + ", group " +
         (group ? std::string(group->gr_name) : std::to_string(info.st_gid)) + ", mode " + mode;
}

std::string check_bits(const UserIdentity& user, const fs::path& path, mode_t needed, std::string_view what) {
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0) return path.string() + ": cannot be read at all";
  if (user.uid == 0) return {};  // root passes the mode bits
  if ((granted(user, info) & needed) == needed) return {};
  return path.string() + ": not " + std::string(what) + " by " + user.name + " (" + owner_text(info) + ")";
}

}  // namespace

std::optional<UserIdentity> lookup_user(const std::string& name) {
  const passwd* entry = ::getpwnam(name.c_str());
  if (entry == nullptr) return std::nullopt;
  UserIdentity user{name, entry->pw_uid, entry->pw_gid, {}};
  int count = 64;
  user.groups.resize(static_cast<std::size_t>(count));
  if (::getgrouplist(name.c_str(), entry->pw_gid, user.groups.data(), &count) < 0) {
    user.groups.resize(static_cast<std::size_t>(count));
    ::getgrouplist(name.c_str(), entry->pw_gid, user.groups.data(), &count);
  }
  user.groups.resize(static_cast<std::size_t>(std::max(count, 0)));
  return user;
}

std::string access_problem(const UserIdentity& user, const fs::path& path, Access access) {
  const fs::path absolute = fs::absolute(path).lexically_normal();
  std::error_code ec;
  if (access != Access::Write && !fs::exists(absolute, ec)) return absolute.string() + ": does not exist";
  fs::path target = absolute;
  bool creates = false;
  while (!fs::exists(target, ec) && target.has_parent_path() && target != target.parent_path()) {
    target = target.parent_path();  // rcand creates what is missing below the nearest existing directory
    creates = true;
  }
  // Every directory above the target must be searchable.
  for (fs::path dir = target.parent_path(); !dir.empty(); dir = dir.parent_path()) {
    if (auto problem = check_bits(user, dir, S_IXOTH, "searchable"); !problem.empty()) return problem;
    if (dir == dir.parent_path()) break;
  }
  if (creates) return check_bits(user, target, S_IWOTH | S_IXOTH, "writable");
  switch (access) {
    case Access::Read: return check_bits(user, target, fs::is_directory(target, ec) ? S_IROTH | S_IXOTH : S_IROTH, "readable");
    case Access::Write: return check_bits(user, target, fs::is_directory(target, ec) ? S_IWOTH | S_IXOTH : S_IWOTH, "writable");
    case Access::ReadWrite: return check_bits(user, target, S_IROTH | S_IWOTH, "readable and writable");
    case Access::Search: return check_bits(user, target, S_IXOTH, "searchable");
  }
  return {};
}

}  // namespace rcand
