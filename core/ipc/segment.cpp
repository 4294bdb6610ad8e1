#include "core/ipc/segment.hpp"

#include <signal.h>

#include <cerrno>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace cnc::ipc {

void validate_instance_name(const std::string& instance) {
  if (instance.empty() || instance.size() > 48) {
    throw std::invalid_argument("instance name \"" + instance + "\": expected 1 to 48 characters");
  }
  for (char c : instance) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' || c == '_';
    if (!ok) throw std::invalid_argument("instance name \"" + instance + "\": use letters, digits, '-' and '_'");
  }
}

std::string shm_name(const std::string& instance) { return "/cnc-" + instance; }
std::string lock_path(const std::string& instance) { return "/dev/shm/cnc-" + instance + ".lock"; }
std::string admin_socket_path(const std::string& instance) { return "/dev/shm/cnc-" + instance + ".hal"; }

std::string default_instance() {
  const char* env = std::getenv("CNC_INSTANCE");
  return env && *env ? std::string(env) : std::string("default");
}

std::optional<uint64_t> process_start_time(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  if (!in) return std::nullopt;
  std::string content((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // The command name (field 2) may contain spaces: fields resume after ')'.
  const auto close = content.rfind(')');
  if (close == std::string::npos) return std::nullopt;
  std::istringstream rest(content.substr(close + 2));
  std::string field;
  // After ')': field 3 is state; starttime is field 22.
  for (int i = 3; i <= 22; ++i) {
    if (!(rest >> field)) return std::nullopt;
  }
  return std::strtoull(field.c_str(), nullptr, 10);
}

bool process_alive(int pid, uint64_t start_time) {
  if (pid <= 0) return false;
  if (::kill(pid, 0) != 0 && errno != EPERM) return false;
  const auto st = process_start_time(pid);
  return st && *st == start_time;
}

}  // namespace cnc::ipc
