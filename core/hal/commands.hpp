// The halcmd language: the commands of .hal files (loadrt, net, setp, addf,
// ...) and of interactive halcmd (show, getp, list, save, ...). One
// interpreter serves both the HAL files the daemon runs at start-up and
// halcmd requests from other processes. Non-realtime.
#pragma once

#include <filesystem>
#include <mutex>
#include <string>
#include <string_view>
#include <cstdint>
#include <sys/types.h>
#include <vector>

#include "core/hal/component.hpp"

namespace cnc::hal {

// A component made at run time by a client process with `newcomp` and
// `newpin`; the client writes its pins with `setr` and reads them with
// `getp`. It has no realtime function.
class RemoteComponent : public Component {
 public:
  RemoteComponent(Hal& hal, const std::string& name);
  void add_pin(const std::string& name, Type type, PinDir dir);
};

class CommandInterpreter {
 public:
  CommandInterpreter(Hal& hal, const ComponentRegistry& registry, const ini::IniFile* ini, MessageQueue* messages);
  ~CommandInterpreter();

  // Where a line comes from: a HAL file the configuration names (trusted
  // as the configuration is), or a halcmd client at run time, which may not
  // make the controller read files (`source`: halcmd reads them itself,
  // with its user's permissions, and sends their lines).
  enum class Origin : uint8_t { File, Client };

  // Executes one line; returns what halcmd prints. Throws HalError with the
  // reason (the caller adds file and line).
  std::string execute(std::string_view line, Origin origin = Origin::File);

  // Runs a .hal file: every line in order; the first error stops it and
  // throws ConfigError naming the file and line.
  void run_file(const std::filesystem::path& path);
  // Runs text as if it were a file called `name`.
  void run_text(std::string_view text, const std::string& name);

  // [SECTION]KEY, [SECTION](KEY), $VAR and $(VAR) replaced by their values.
  std::string substitute(std::string_view line) const;

  // Programs started with loadusr: stopped (SIGTERM, then SIGKILL) here.
  void stop_user_programs();

 private:
  std::string dispatch(const std::vector<std::string>& words, Origin origin);
  // The program loadusr may start: inside one of the allowed folders
  // ([HAL]LOADUSR_PATH, the configuration's folder, the controller's own
  // bin folder), a regular executable file; throws HalError otherwise.
  std::filesystem::path loadusr_program(const std::string& name) const;
  std::string cmd_loadrt(const std::vector<std::string>& w);
  std::string cmd_loadusr(const std::vector<std::string>& w);
  std::string cmd_show(const std::vector<std::string>& w) const;
  std::string cmd_list(const std::vector<std::string>& w) const;
  std::string cmd_save() const;

  Hal& hal_;
  const ComponentRegistry& registry_;
  const ini::IniFile* ini_;
  MessageQueue* messages_;
  std::recursive_mutex mutex_;
  std::vector<pid_t> children_;
  std::vector<std::filesystem::path> file_stack_;
};

// Splits a halcmd line into words: blanks separate, double quotes group,
// '#' starts a comment outside quotes.
std::vector<std::string> tokenize_hal_line(std::string_view line);

}  // namespace cnc::hal
