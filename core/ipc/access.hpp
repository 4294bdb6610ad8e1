// Who may command a controller (docs/security.md): the user the controller
// runs as, root, and, when the configuration names one, the members of a
// group that is trusted as fully as that user. The shared segment and the
// halcmd socket get the matching file modes; the halcmd socket also checks
// each peer's credentials, since a socket's mode is only a first gate.
#pragma once

#include <sys/types.h>

#include <optional>
#include <string>

namespace cnc::ipc {

struct AccessPolicy {
  uid_t owner_uid = 0;
  std::optional<gid_t> group;  // the trusted group, if any
  std::string group_name;

  // The current user, plus the named group (throws std::runtime_error when
  // the group does not exist). Empty name: the owner alone.
  static AccessPolicy for_current_user(const std::string& group_name = "");
  // 0600, or 0660 with a trusted group.
  mode_t file_mode() const noexcept { return group ? 0660 : 0600; }
  // Sets mode and group on a file the controller created; throws naming it.
  void apply(int fd, const std::string& what) const;
  void apply(const std::string& path, const std::string& what) const;
  // The owner, root, or a member of the trusted group.
  bool permits(uid_t uid) const;
};

}  // namespace cnc::ipc
