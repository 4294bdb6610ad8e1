// Private to the task controller: the helpers its parts share and its
// run-from-line records (task_controller.cpp: configuration, construction
// and the motion link; task_commands.cpp: the operator's commands;
// task_program.cpp: running programs and MDI; task_status.cpp: following
// motion's state and the status).
#pragma once

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <deque>
#include <fstream>
#include <memory>
#include <string>

#include "core/ini/ini_file.hpp"
#include "core/interp/line_reader.hpp"
#include "core/task/task_controller.hpp"
#include "core/util/strings.hpp"

namespace cnc::task {
namespace detail {

// A figure for a message: six significant digits ("55000", not "55000.00000000001").
inline std::string figure(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// "process 1234 (cnc)": who asked, for the message channel.
inline std::string describe_process(int32_t pid) {
  if (pid <= 0) return "an unknown process";
  std::ifstream in("/proc/" + std::to_string(pid) + "/comm");
  std::string name;
  std::getline(in, name);
  return "process " + std::to_string(pid) + " (" + (name.empty() ? std::string("no longer running") : name) + ")";
}

// Lines of a program the interpreter has just opened (for the status);
// a regular file only, like everything the interpreter reads.
inline int count_lines(const std::string& path) {
  int fd = -1;
  try {
    fd = interp::open_regular_file(path);
  } catch (const interp::InterpError&) {
    return 0;  // replaced since the interpreter opened it: the count is not known
  }
  int n = 0;
  char buf[65536];
  for (;;) {
    const ssize_t got = ::read(fd, buf, sizeof buf);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) break;
    for (ssize_t i = 0; i < got; ++i) n += buf[i] == '\n' ? 1 : 0;
  }
  ::close(fd);
  return n;
}

// Reading and executing per task cycle, in the program, MDI, run from line
// and its preview.
inline constexpr int64_t kReadBudgetNs = 2'000'000;

// An interpreter error as the message channel shows it: file:line: text,
// without the file for an MDI line.
inline std::string describe(const interp::InterpError& e) {
  if (e.file().empty() || e.file() == "<mdi>") return e.message();
  return e.file() + ":" + std::to_string(e.line()) + ": " + e.message();
}


}  // namespace detail

// Run from line in progress: what the lines before the target left behind.
struct TaskController::Reconstruction {
  int line = 0;
  bool done = false;
  std::string error;  // empty: done and running
  std::deque<Item> kept;
  Item spindle, flood, mist, tool_change, tool_offset;
  bool have_spindle = false, have_flood = false, have_mist = false, have_tool = false, have_offset = false;
};

// Run-from-line preview: a scratch interpreter stepped within the budget.
struct TaskController::PreviewJob {
  int line = 0;
  std::deque<Item> items;
  MachineView view;
  std::unique_ptr<TaskCanon> canon;
  std::unique_ptr<interp::Interpreter> interp;
};

}  // namespace cnc::task
