#include "core/ipc/access.hpp"

#include <grp.h>
#include <pwd.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <vector>

namespace cnc::ipc {

AccessPolicy AccessPolicy::for_current_user(const std::string& group_name) {
  AccessPolicy p;
  p.owner_uid = ::geteuid();
  if (!group_name.empty()) {
    std::vector<char> buf(16384);
    struct group g {};
    struct group* found = nullptr;
    if (::getgrnam_r(group_name.c_str(), &g, buf.data(), buf.size(), &found) != 0 || !found) {
      throw std::runtime_error("group \"" + group_name + "\" does not exist");
    }
    p.group = found->gr_gid;
    p.group_name = group_name;
  }
  return p;
}

void AccessPolicy::apply(int fd, const std::string& what) const {
  if (group && ::fchown(fd, static_cast<uid_t>(-1), *group) != 0) {
    throw std::runtime_error("cannot give " + what + " to group " + group_name + ": " + std::strerror(errno));
  }
  if (::fchmod(fd, file_mode()) != 0) throw std::runtime_error("cannot set the mode of " + what + ": " + std::strerror(errno));
}

void AccessPolicy::apply(const std::string& path, const std::string& what) const {
  if (group && ::lchown(path.c_str(), static_cast<uid_t>(-1), *group) != 0) {
    throw std::runtime_error("cannot give " + what + " to group " + group_name + ": " + std::strerror(errno));
  }
  if (::chmod(path.c_str(), file_mode()) != 0) {
    throw std::runtime_error("cannot set the mode of " + what + ": " + std::strerror(errno));
  }
}

bool AccessPolicy::permits(uid_t uid) const {
  if (uid == 0 || uid == owner_uid) return true;
  if (!group) return false;
  std::vector<char> buf(16384);
  passwd pw{};
  passwd* found = nullptr;
  if (::getpwuid_r(uid, &pw, buf.data(), buf.size(), &found) != 0 || !found) return false;
  if (found->pw_gid == *group) return true;
  int n = 64;
  std::vector<gid_t> groups(static_cast<std::size_t>(n));
  if (::getgrouplist(found->pw_name, found->pw_gid, groups.data(), &n) < 0) {
    groups.resize(static_cast<std::size_t>(n));
    if (::getgrouplist(found->pw_name, found->pw_gid, groups.data(), &n) < 0) return false;
  }
  for (int i = 0; i < n; ++i) {
    if (groups[static_cast<std::size_t>(i)] == *group) return true;
  }
  return false;
}

}  // namespace cnc::ipc
