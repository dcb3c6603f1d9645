#include "libs/base/file_trust.hpp"

#include <grp.h>
#include <pwd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <vector>

namespace rcand {
namespace {

std::string user_text(uid_t uid) {
  passwd entry{};
  passwd* found = nullptr;
  std::vector<char> buffer(16 * 1024);
  if (::getpwuid_r(uid, &entry, buffer.data(), buffer.size(), &found) == 0 && found != nullptr)
    return std::string(found->pw_name) + " (uid " + std::to_string(uid) + ")";
  return "uid " + std::to_string(uid);
}

std::string group_text(gid_t gid) {
  group entry{};
  group* found = nullptr;
  std::vector<char> buffer(64 * 1024);
  if (::getgrgid_r(gid, &entry, buffer.data(), buffer.size(), &found) == 0 && found != nullptr)
    return std::string(found->gr_name);
  return "gid " + std::to_string(gid);
}

bool trusted_uid(uid_t uid, uid_t user) { return uid == 0 || uid == user; }

}  // namespace

bool group_only_trusted(gid_t gid, uid_t user) {
  group entry{};
  group* found = nullptr;
  std::vector<char> buffer(64 * 1024);
  if (::getgrgid_r(gid, &entry, buffer.data(), buffer.size(), &found) != 0 || found == nullptr) return false;
  int members = 0;
  std::vector<char> user_buffer(16 * 1024);
  for (char** name = found->gr_mem; name != nullptr && *name != nullptr; ++name) {
    passwd member{};
    passwd* known = nullptr;
    if (::getpwnam_r(*name, &member, user_buffer.data(), user_buffer.size(), &known) != 0 || known == nullptr) return false;
    if (!trusted_uid(known->pw_uid, user)) return false;
    ++members;
  }
  // Those whose primary group it is: the user database, enumerated (main thread: config loads and reloads).
  bool only_trusted = true;
  ::setpwent();
  passwd member{};
  passwd* next = nullptr;
  while (only_trusted && ::getpwent_r(&member, user_buffer.data(), user_buffer.size(), &next) == 0 && next != nullptr) {
    if (next->pw_gid != gid) continue;
    only_trusted = trusted_uid(next->pw_uid, user);
    ++members;
  }
  ::endpwent();
  return only_trusted && members > 0;
}

std::string untrusted_writers(const std::filesystem::path& path, const struct stat& info, uid_t user, bool sticky_ok) {
  std::vector<std::string> problems, fixes;
  if (!trusted_uid(info.st_uid, user)) {
    problems.push_back("owned by " + user_text(info.st_uid) + ", not by root or " + user_text(user));
    fixes.push_back("chown root '" + path.string() + "'");
  }
  const bool sticky_dir = sticky_ok && S_ISDIR(info.st_mode) && (info.st_mode & S_ISVTX) != 0;
  const bool group_writes = (info.st_mode & S_IWGRP) != 0 && !sticky_dir && !group_only_trusted(info.st_gid, user);
  const bool others_write = (info.st_mode & S_IWOTH) != 0 && !sticky_dir;
  char mode[8];
  std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(info.st_mode & 07777));
  if (group_writes)
    problems.push_back("writable by group " + group_text(info.st_gid) + ", which has other members (mode " + mode + ")");
  if (others_write) problems.push_back(std::string("writable by every user (mode ") + mode + ")");
  if (group_writes || others_write)
    fixes.push_back(std::string("chmod ") +
                    (group_writes && others_write ? "go-w"
                     : group_writes               ? "g-w"
                                                  : "o-w") +
                    " '" + path.string() + "'");
  if (problems.empty()) return {};
  std::string text;
  for (const auto& problem : problems) text += (text.empty() ? "" : " and ") + problem;
  text += "; fix: ";
  for (std::size_t i = 0; i < fixes.size(); ++i) text += (i ? " && " : "") + fixes[i];
  return text;
}

std::string untrusted_writers(const std::filesystem::path& path, uid_t user, bool sticky_ok) {
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0) return std::string("cannot be checked: ") + std::strerror(errno);
  return untrusted_writers(path, info, user, sticky_ok);
}

}  // namespace rcand
