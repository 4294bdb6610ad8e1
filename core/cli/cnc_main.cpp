// cnc: the command-line client of a running controller: status, messages,
// and every operator command (E-stop, machine on, modes, MDI, programs,
// jogging, homing, overrides...). Each command is sent through the shared
// segment's command channel and answered by the controller; E-stop also,
// and first, goes through the segment's E-stop word, which motion acts on
// in the servo thread without a channel or the task cycle.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "core/cli/status_format.hpp"
#include "core/ipc/client.hpp"
#include "core/ipc/command_check.hpp"
#include "core/ipc/operator_commands.hpp"
#include "core/util/pose.hpp"
#include "core/util/strings.hpp"
#include "core/util/time.hpp"

using namespace cnc;
using ipc::Command;
using ipc::CommandType;

namespace {

struct Context {
  std::string instance;
  double timeout_s = 30;
  bool timeout_given = false;  // --timeout on the command line
  std::vector<std::string> args;  // after the command name
};

[[noreturn]] void fail_usage(const std::string& msg) {
  std::fprintf(stderr, "cnc: %s (see cnc help)\n", msg.c_str());
  std::exit(2);
}

// A real argument: finite and within +-limit (the controller checks the
// same bounds; refusing here names the argument as typed).
double number(const std::string& s, const char* what, double limit = ipc::kMaxLinearArgument) {
  const auto v = parse_double(s);
  if (!v) fail_usage(std::string(what) + ": \"" + s + "\" is not a number");
  if (std::fabs(*v) > limit) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%g", limit);
    fail_usage(std::string(what) + ": " + s + " is out of range (at most " + buf + " in magnitude)");
  }
  return *v;
}

// An integer argument in [lo, hi]: never wraps into another joint, macro
// or line.
int integer(const std::string& s, const char* what, int64_t lo = 0, int64_t hi = INT32_MAX) {
  const auto v = parse_int(s);
  if (!v) fail_usage(std::string(what) + ": \"" + s + "\" is not an integer");
  if (*v < lo || *v > hi) {
    fail_usage(std::string(what) + ": " + s + " is out of range (expected " + std::to_string(lo) + " to " +
               std::to_string(hi) + ")");
  }
  return static_cast<int>(*v);
}

bool on_off(const std::string& s) {
  const auto b = parse_bool(s);
  if (!b) fail_usage("expected on or off, got \"" + s + "\"");
  return *b;
}

// Between `n` and `most` arguments (default: exactly n).
void need_args(const Context& c, std::size_t n, const char* usage, std::size_t most = 0) {
  if (c.args.size() < n || c.args.size() > std::max(n, most)) fail_usage(std::string("usage: cnc ") + usage);
}

// Sends a command and waits for its answer; prints a rejection's reason.
int send(const Context& c, const Command& cmd) {
  ipc::Client client(c.instance);
  const auto timeout = std::chrono::milliseconds(static_cast<int64_t>(c.timeout_s * 1000));
  const ipc::CommandResult r = client.execute(cmd, timeout);
  switch (r.state) {
    case ipc::CommandState::Done:
      return 0;
    case ipc::CommandState::Rejected:
      std::fprintf(stderr, "cnc: %s rejected: %s\n", ipc::to_string(cmd.type), r.reason.c_str());
      return 1;
    case ipc::CommandState::Executing:
    case ipc::CommandState::Received:
      std::fprintf(stderr, "cnc: %s still %s after %.0f s\n", ipc::to_string(cmd.type), ipc::to_string(r.state),
                   c.timeout_s);
      return 3;
    case ipc::CommandState::None:
      std::fprintf(stderr, "cnc: %s: no answer from the controller%s%s\n", ipc::to_string(cmd.type),
                   r.reason.empty() ? "" : ": ", r.reason.c_str());
      return 3;
  }
  return 3;
}

// Homing takes seconds: while the command runs, say which joints are
// homing and which are done, one line per change.
int send_home(const Context& c, const Command& cmd) {
  ipc::Client client(c.instance);
  const uint32_t serial = client.send(cmd);
  const int64_t deadline = monotonic_ns() + static_cast<int64_t>(c.timeout_s * 1e9);
  std::string last;
  for (;;) {
    const ipc::CommandResult r = client.wait(serial, std::chrono::milliseconds(200));
    if (r.state == ipc::CommandState::Done) {
      std::printf("homed\n");
      return 0;
    }
    if (r.state == ipc::CommandState::Rejected) {
      std::fprintf(stderr, "cnc: %s rejected: %s\n", ipc::to_string(cmd.type), r.reason.c_str());
      return 1;
    }
    const ipc::Status s = client.status();
    std::string homing, homed;
    for (int j = 0; j < kMaxJoints; ++j) {
      const ipc::JointStatus& js = s.joints[static_cast<std::size_t>(j)];
      if (!js.active) continue;
      if (js.homing) homing += " " + std::to_string(j);
      else if (js.homed) homed += " " + std::to_string(j);
    }
    const std::string line = "homing: joint" + (homing.empty() ? std::string("s -") : homing) +
                             (homed.empty() ? "" : "; homed:" + homed);
    if (line != last) {
      std::printf("%s\n", line.c_str());
      std::fflush(stdout);
      last = line;
    }
    if (monotonic_ns() > deadline || !client.controller_alive()) {
      std::fprintf(stderr, "cnc: %s still %s after %.0f s\n", ipc::to_string(cmd.type), ipc::to_string(r.state),
                   c.timeout_s);
      return 3;
    }
  }
}

Command cmd_of(CommandType t) { return ipc::make_command(t); }

Command with_text(CommandType t, const std::string& text) {
  Command c = cmd_of(t);
  if (text.size() > decltype(c.text)::capacity()) fail_usage("text longer than " + std::to_string(decltype(c.text)::capacity()) + " characters");
  c.text.assign(text);
  return c;
}

// A command with text from the command line: too long a text is a usage
// error naming it.
Command checked(Command (*build)(const std::string&), const std::string& text) {
  try {
    return build(text);
  } catch (const std::invalid_argument& e) {
    fail_usage(e.what());
  }
}

std::string join_args(const Context& c, std::size_t from = 0) {
  std::string out;
  for (std::size_t i = from; i < c.args.size(); ++i) out += (i > from ? " " : "") + c.args[i];
  return out;
}

// "x".."w" -> axis (teleop jog), a number -> joint (free jog).
struct Target {
  int index;
  bool joint;
};
Target target(const std::string& s) {
  if (s.size() == 1 && axis_index(s[0]) >= 0) return {axis_index(s[0]), false};
  return {integer(s, "joint", 0, kMaxJoints - 1), true};
}

int joint_or_all(const std::string& s) { return s == "all" ? -1 : integer(s, "joint", 0, kMaxJoints - 1); }

int cmd_status(const Context& c) {
  bool json = false;
  for (const auto& a : c.args) {
    if (a == "--json") json = true;
    else fail_usage("status: unknown option " + a);
  }
  ipc::Client client(c.instance);
  const ipc::Status s = client.status();
  const ipc::Liveness live = client.liveness(s);
  std::fputs((json ? cli::status_json(s, 2, &live) + "\n" : cli::format_status(s, &live)).c_str(), stdout);
  return 0;
}

// E-stop through the segment's E-stop word (acted on by motion in the servo
// thread, acknowledged there): it needs no command channel and no task
// cycle. The task is told too, when a channel is free, so that it records
// who asked; success does not depend on it.
int cmd_estop(const Context& c) {
  ipc::Client client(c.instance);
  const uint64_t request = client.request_estop();
  uint32_t serial = 0;
  std::string not_told;
  try {
    if (!client.try_send(ipc::commands::set_state(ipc::TaskState::Estop), serial)) not_told = "its command queue is full";
  } catch (const ipc::ClientError& e) {
    not_told = e.what();
  }
  const double budget_s = std::min(c.timeout_s, 5.0);
  const ipc::Liveness live = client.liveness(client.status());
  if (live.servo_age_ns >= 0) {
    if (client.wait_estop_acknowledged(request, std::chrono::milliseconds(static_cast<int64_t>(budget_s * 1000)))) {
      if (!not_told.empty()) {
        std::fprintf(stderr, "cnc: estop: done in the servo thread; the task was not told (%s)\n", not_told.c_str());
      }
      return 0;
    }
    std::fprintf(stderr, "cnc: estop: requested, but motion did not act on it within %.1f s%s\n", budget_s,
                 live.servo_stalled ? " (motion-controller is not running: only the drives' watchdogs stop them)" : "");
    return 3;
  }
  // A controller without motion: the task's answer is all there is.
  if (!not_told.empty()) {
    std::fprintf(stderr, "cnc: estop: %s\n", not_told.c_str());
    return 1;
  }
  const ipc::CommandResult r = client.wait(serial, std::chrono::milliseconds(static_cast<int64_t>(budget_s * 1000)));
  if (r.state == ipc::CommandState::Done) return 0;
  std::fprintf(stderr, "cnc: estop: %s\n", r.state == ipc::CommandState::Rejected ? r.reason.c_str() : "no answer from the controller");
  return r.state == ipc::CommandState::Rejected ? 1 : 3;
}

int cmd_watch(const Context& c) {
  double interval = 0.5;
  bool json = false;
  int count = -1;
  for (std::size_t i = 0; i < c.args.size(); ++i) {
    if (c.args[i] == "--interval" && i + 1 < c.args.size()) interval = number(c.args[++i], "interval", 3600);
    else if (c.args[i] == "--count" && i + 1 < c.args.size()) count = integer(c.args[++i], "count", 1);
    else if (c.args[i] == "--json") json = true;
    else fail_usage("watch: unknown option " + c.args[i]);
  }
  if (interval <= 0) fail_usage("watch: --interval must be more than 0 s");
  ipc::Client client(c.instance);
  const bool tty = ::isatty(1);
  for (int n = 0; count < 0 || n < count; ++n) {
    if (!client.controller_alive()) {
      std::fprintf(stderr, "cnc: controller not running (it stopped)\n");
      return 1;
    }
    const ipc::Status s = client.status();
    const ipc::Liveness live = client.liveness(s);
    if (tty && !json) std::fputs("\033[H\033[2J", stdout);
    std::fputs((json ? cli::status_json(s, -1, &live) + "\n" : cli::format_status(s, &live)).c_str(), stdout);
    std::fflush(stdout);
    std::this_thread::sleep_for(std::chrono::milliseconds(static_cast<int64_t>(interval * 1000)));
  }
  return 0;
}

void print_message(const Message& m) {
  const time_t secs = static_cast<time_t>(m.time_ns / 1'000'000'000);
  tm local{};
  localtime_r(&secs, &local);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%Y-%m-%d %H:%M:%S", &local);
  std::printf("%s %-7s [%s] %s\n", stamp, to_string(m.kind), m.source.c_str(), m.text.c_str());
}

int cmd_messages(const Context& c) {
  bool follow = false, all = false;
  for (const auto& a : c.args) {
    if (a == "--follow" || a == "-f") follow = true;
    else if (a == "--all") all = true;
    else fail_usage("messages: unknown option " + a);
  }
  ipc::Client client(c.instance);
  if (all || !follow) client.rewind_messages();
  for (;;) {
    Message m;
    uint64_t lost = 0;
    while (client.next_message(m, &lost)) {
      if (lost) {
        std::printf("(%llu messages lost: the reader fell behind)\n", static_cast<unsigned long long>(lost));
        lost = 0;
      }
      print_message(m);
    }
    std::fflush(stdout);
    if (!follow) return 0;
    if (!client.controller_alive()) return 0;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

int cmd_wait_ready(const Context& c) {
  const int64_t deadline = monotonic_ns() + static_cast<int64_t>(c.timeout_s * 1e9);
  std::string last;
  int32_t starting_pid = 0;  // a controller seen starting up
  while (monotonic_ns() < deadline) {
    try {
      ipc::Client client(c.instance);
      if (client.controller_ready()) return 0;
      starting_pid = client.owner_pid();
    } catch (const std::exception& e) {
      last = e.what();
      if (starting_pid > 0) {
        // It was starting and is gone: waiting longer cannot help.
        std::fprintf(stderr,
                     "cnc: the controller (pid %d) stopped during start-up, before it was ready: its error is in "
                     "its own output (standard error or log)\n",
                     starting_pid);
        return 1;
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  std::fprintf(stderr, "cnc: controller not ready after %.0f s%s%s\n", c.timeout_s, last.empty() ? "" : ": ", last.c_str());
  return 1;
}

// Follows a running program until it ends; prints progress and a summary.
int cmd_wait_program(const Context& c) {
  ipc::Client client(c.instance);
  const int64_t start = monotonic_ns();
  int last_line = -1;
  int64_t last_print = 0;
  bool seen_running = false;
  for (;;) {
    if (!client.controller_alive()) {
      std::fprintf(stderr, "cnc: the controller stopped\n");
      return 1;
    }
    const ipc::Status s = client.status();
    const bool running = s.task.interp_state != ipc::InterpState::Idle;
    seen_running = seen_running || running;
    const int64_t now = monotonic_ns();
    if (running && (s.task.current_line != last_line) && now - last_print > 250'000'000) {
      std::printf("  line %5d of %d   X%9.3f Y%9.3f Z%9.3f   tool %d   %s%s\n", s.task.current_line,
                  s.task.total_lines, s.motion.position[0], s.motion.position[1], s.motion.position[2],
                  s.io.tool_in_spindle, ipc::to_string(s.task.exec_state), s.task.paused ? " PAUSED" : "");
      std::fflush(stdout);
      last_line = s.task.current_line;
      last_print = now;
    }
    if (!running && (seen_running || now - start > 2'000'000'000)) {
      std::printf("program done: %s\n  time %.2f s, %lld blocks, %d errors, tool %d in the spindle\n",
                  s.task.file.c_str(), static_cast<double>(s.task.program_elapsed_ns) * 1e-9,
                  static_cast<long long>(s.task.blocks_executed), s.task.errors_since_start, s.io.tool_in_spindle);
      std::printf("  final position X%.4f Y%.4f Z%.4f (machine)\n", s.motion.position[0], s.motion.position[1],
                  s.motion.position[2]);
      return s.task.errors_since_start == 0 ? 0 : 1;
    }
    // A program takes as long as it takes: only an explicit --timeout ends
    // the wait (the 30 s default is for commands).
    if (c.timeout_given && static_cast<double>(now - start) * 1e-9 > c.timeout_s) {
      std::fprintf(stderr, "cnc: the program is still running after %.0f s\n", c.timeout_s);
      return 3;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

struct Entry {
  const char* usage;
  const char* help;
  std::function<int(Context&)> run;
};

std::map<std::string, Entry> commands() {
  std::map<std::string, Entry> m;
  m["status"] = {"status [--json]", "print the controller's status", cmd_status};
  m["watch"] = {"watch [--interval S] [--count N] [--json]", "print the status repeatedly", cmd_watch};
  m["messages"] = {"messages [--follow] [--all]", "print the error/message channel", cmd_messages};
  m["wait-ready"] = {"wait-ready", "wait until the controller is up (see --timeout)", cmd_wait_ready};
  m["wait-program"] = {"wait-program",
                       "follow the running program to its end, then print a summary (no time limit unless --timeout)",
                       cmd_wait_program};
  m["ping"] = {"ping", "check that the controller answers commands",
               [](Context& c) { return send(c, cmd_of(CommandType::Ping)); }};
  m["shutdown"] = {"shutdown", "stop the controller (drives to a safe state first)",
                   [](Context& c) { return send(c, cmd_of(CommandType::Shutdown)); }};
  m["error"] = {"error TEXT", "post an operator error", [](Context& c) {
                  need_args(c, 1, "error TEXT", SIZE_MAX);
                  return send(c, checked(ipc::commands::operator_error, join_args(c)));
                }};
  m["text"] = {"text TEXT", "post an operator text", [](Context& c) {
                 need_args(c, 1, "text TEXT", SIZE_MAX);
                 return send(c, checked(ipc::commands::operator_text, join_args(c)));
               }};
  m["display"] = {"display TEXT", "post an operator display message", [](Context& c) {
                    need_args(c, 1, "display TEXT", SIZE_MAX);
                    return send(c, checked(ipc::commands::operator_display, join_args(c)));
                  }};
  m["alarms"] = {"alarms [--all] | alarms ack ID|all",
                 "list the controller's active alarms (--all: with acknowledged ones), or acknowledge one or all",
                 [](Context& c) {
                   if (!c.args.empty() && c.args[0] == "ack") {
                     need_args(c, 2, "alarms ack ID|all");
                     const uint32_t id = c.args[1] == "all" ? 0U
                                                            : static_cast<uint32_t>(integer(c.args[1], "alarm id", 1));
                     return send(c, ipc::commands::acknowledge_alarm(id));
                   }
                   bool all = false;
                   for (const auto& a : c.args) {
                     if (a == "--all") all = true;
                     else fail_usage("alarms: unknown option " + a);
                   }
                   ipc::Client client(c.instance);
                   std::fputs(cli::format_alarms(client.status().alarms, all).c_str(), stdout);
                   return 0;
                 }};
  m["estop"] = {"estop", "E-stop (acted on in the servo thread, needs no free channel)", cmd_estop};
  m["estop-reset"] = {"estop-reset", "reset the E-stop",
                      [](Context& c) { return send(c, ipc::commands::set_state(ipc::TaskState::EstopReset)); }};
  m["off"] = {"off", "machine off", [](Context& c) { return send(c, ipc::commands::set_state(ipc::TaskState::Off)); }};
  m["on"] = {"on", "machine on", [](Context& c) { return send(c, ipc::commands::set_state(ipc::TaskState::On)); }};
  m["mode"] = {"mode manual|auto|mdi", "change the task mode", [](Context& c) {
                 need_args(c, 1, "mode manual|auto|mdi");
                 const std::string m = to_lower(c.args[0]);
                 const int v = m == "manual" ? 1 : m == "auto" ? 2 : m == "mdi" ? 3 : 0;
                 if (!v) fail_usage("mode: expected manual, auto or mdi");
                 return send(c, ipc::commands::set_mode(static_cast<ipc::TaskMode>(v)));
               }};
  m["mdi"] = {"mdi G-CODE...", "execute one MDI line", [](Context& c) {
                need_args(c, 1, "mdi G-CODE", SIZE_MAX);
                return send(c, checked(ipc::commands::mdi, join_args(c)));
              }};
  m["macro"] = {"macro N", "run [MDI_COMMAND_LIST] macro N", [](Context& c) {
                  need_args(c, 1, "macro N");
                  return send(c, ipc::commands::macro(integer(c.args[0], "macro", 0, 999)));
                }};
  m["open"] = {"open FILE", "open a program", [](Context& c) {
                 need_args(c, 1, "open FILE");
                 std::string path = c.args[0];
                 if (!path.empty() && path[0] != '/') {
                   char cwd[4096];
                   if (::getcwd(cwd, sizeof cwd)) path = std::string(cwd) + "/" + path;
                 }
                 return send(c, checked(ipc::commands::open, path));
               }};
  m["run"] = {"run [LINE]", "run the open program (from LINE)", [](Context& c) {
                need_args(c, 0, "run [LINE]", 1);
                return send(c, ipc::commands::run(c.args.empty() ? 0 : integer(c.args[0], "line")));
              }};
  m["pause"] = {"pause", "pause the program", [](Context& c) { return send(c, ipc::commands::pause()); }};
  m["resume"] = {"resume", "resume the program", [](Context& c) { return send(c, ipc::commands::resume()); }};
  m["step"] = {"step", "execute one block", [](Context& c) { return send(c, ipc::commands::step()); }};
  m["abort"] = {"abort", "abort motion and the program", [](Context& c) { return send(c, ipc::commands::abort()); }};
  m["close"] = {"close", "close the program", [](Context& c) { return send(c, ipc::commands::close()); }};
  m["optional-stop"] = {"optional-stop on|off", "M1 stops or not", [](Context& c) {
                          need_args(c, 1, "optional-stop on|off");
                          return send(c, ipc::commands::optional_stop(on_off(c.args[0])));
                        }};
  m["block-delete"] = {"block-delete on|off", "skip lines starting with /", [](Context& c) {
                         need_args(c, 1, "block-delete on|off");
                         return send(c, ipc::commands::block_delete(on_off(c.args[0])));
                       }};
  m["home"] = {"home JOINT|all", "home a joint or all joints", [](Context& c) {
                 need_args(c, 1, "home JOINT|all");
                 return send_home(c, ipc::commands::home(joint_or_all(c.args[0])));
               }};
  m["unhome"] = {"unhome JOINT|all", "forget a joint's home", [](Context& c) {
                   need_args(c, 1, "unhome JOINT|all");
                   return send(c, ipc::commands::unhome(joint_or_all(c.args[0])));
                 }};
  m["override-limits"] = {"override-limits", "allow jogging off a limit switch (until the next jog ends)",
                          [](Context& c) { return send(c, ipc::commands::override_limits()); }};
  m["jog"] = {"jog AXIS|JOINT VELOCITY [DISTANCE]", "jog continuously, or by DISTANCE", [](Context& c) {
                need_args(c, 2, "jog AXIS|JOINT VELOCITY [DISTANCE]", 3);
                const Target t = target(c.args[0]);
                const double v = number(c.args[1], "velocity");
                if (c.args.size() > 2) {
                  return send(c, ipc::commands::jog_increment(t.index, t.joint, v, number(c.args[2], "distance")));
                }
                return send(c, ipc::commands::jog_continuous(t.index, t.joint, v));
              }};
  m["jog-to"] = {"jog-to AXIS|JOINT VELOCITY POSITION", "jog to an absolute position", [](Context& c) {
                   need_args(c, 3, "jog-to AXIS|JOINT VELOCITY POSITION");
                   const Target t = target(c.args[0]);
                   return send(c, ipc::commands::jog_absolute(t.index, t.joint, number(c.args[1], "velocity"),
                                                              number(c.args[2], "position")));
                 }};
  m["jog-stop"] = {"jog-stop AXIS|JOINT", "stop a jog", [](Context& c) {
                     need_args(c, 1, "jog-stop AXIS|JOINT");
                     const Target t = target(c.args[0]);
                     return send(c, ipc::commands::jog_stop(t.index, t.joint));
                   }};
  m["feed-override"] = {"feed-override PERCENT", "feed override", [](Context& c) {
                          need_args(c, 1, "feed-override PERCENT");
                          return send(c, ipc::commands::feed_override(number(c.args[0], "percent", 100 * ipc::kMaxOverrideScale) / 100));
                        }};
  m["rapid-override"] = {"rapid-override PERCENT", "rapid override", [](Context& c) {
                           need_args(c, 1, "rapid-override PERCENT");
                           return send(c, ipc::commands::rapid_override(number(c.args[0], "percent", 100 * ipc::kMaxOverrideScale) / 100));
                         }};
  m["max-velocity"] = {"max-velocity UNITS_PER_S", "maximum velocity override", [](Context& c) {
                         need_args(c, 1, "max-velocity UNITS_PER_S");
                         return send(c, ipc::commands::max_velocity(number(c.args[0], "velocity")));
                       }};
  m["spindle-override"] = {"spindle-override PERCENT", "spindle override", [](Context& c) {
                             need_args(c, 1, "spindle-override PERCENT");
                             return send(c, ipc::commands::spindle_override(number(c.args[0], "percent", 100 * ipc::kMaxOverrideScale) / 100));
                           }};
  m["spindle"] = {"spindle RPM|off", "start (negative: reverse) or stop spindle 0", [](Context& c) {
                    need_args(c, 1, "spindle RPM|off");
                    if (c.args[0] == "off") return send(c, ipc::commands::spindle_off());
                    return send(c, ipc::commands::spindle_on(number(c.args[0], "rpm", ipc::kMaxSpindleRpm)));
                  }};
  m["flood"] = {"flood on|off", "flood coolant", [](Context& c) {
                  need_args(c, 1, "flood on|off");
                  return send(c, ipc::commands::flood(on_off(c.args[0])));
                }};
  m["mist"] = {"mist on|off", "mist coolant", [](Context& c) {
                 need_args(c, 1, "mist on|off");
                 return send(c, ipc::commands::mist(on_off(c.args[0])));
               }};
  m["lube"] = {"lube on|off", "lubrication", [](Context& c) {
                 need_args(c, 1, "lube on|off");
                 return send(c, ipc::commands::lube(on_off(c.args[0])));
               }};
  m["tool-load-table"] = {"tool-load-table", "re-read the tool table file",
                          [](Context& c) { return send(c, ipc::commands::tool_load_table()); }};
  m["tool-set-number"] = {"tool-set-number TOOL", "declare the tool in the spindle (M61)", [](Context& c) {
                            need_args(c, 1, "tool-set-number TOOL");
                            return send(c, ipc::commands::tool_set_number(integer(c.args[0], "tool", 0, 99'999'999)));
                          }};
  m["set"] = {"set PARAMETER INDEX VALUE", "set a motion parameter (SET_xxx)", [](Context& c) {
                need_args(c, 3, "set PARAMETER INDEX VALUE");
                Command cmd = with_text(CommandType::SetParameter, c.args[0]);
                cmd.i[0] = integer(c.args[1], "index", 0, kMaxJoints - 1);
                cmd.d[0] = number(c.args[2], "value", 1e12);
                return send(c, cmd);
              }};
  m["inject"] = {"inject WHAT [VALUE]", "fault injection on simulated machines", [](Context& c) {
                   need_args(c, 1, "inject WHAT [VALUE]", 2);
                   Command cmd = with_text(CommandType::SimInject, c.args[0]);
                   if (c.args.size() > 1) cmd.d[0] = number(c.args[1], "value", 1e12);
                   return send(c, cmd);
                 }};
  return m;
}

void help(const std::map<std::string, Entry>& m) {
  std::printf("usage: cnc [-i INSTANCE] [--timeout S] COMMAND [ARGS...]\n\n"
              "The instance defaults to $CNC_INSTANCE or \"default\". --timeout: how long a\n"
              "command may take (default 30 s); wait-program waits without a limit unless given.\n"
              "Commands:\n");
  for (const auto& [name, e] : m) std::printf("  %-42s %s\n", e.usage, e.help);
}

}  // namespace

int main(int argc, char** argv) {
  Context c;
  c.instance = ipc::default_instance();
  int i = 1;
  for (; i < argc; ++i) {
    const std::string a = argv[i];
    if ((a == "-i" || a == "--instance") && i + 1 < argc) c.instance = argv[++i];
    else if (a == "--timeout" && i + 1 < argc) {
      c.timeout_s = number(argv[++i], "timeout", 1e6);
      c.timeout_given = true;
      if (c.timeout_s <= 0) fail_usage("--timeout must be more than 0 s");
    }
    else break;
  }
  const auto table = commands();
  if (i >= argc || std::strcmp(argv[i], "help") == 0 || std::strcmp(argv[i], "--help") == 0) {
    help(table);
    return i >= argc ? 2 : 0;
  }
  const std::string name = argv[i];
  for (int k = i + 1; k < argc; ++k) c.args.emplace_back(argv[k]);
  const auto it = table.find(name);
  if (it == table.end()) fail_usage("unknown command \"" + name + "\"");
  // A usage without arguments: anything after the name is a mistake.
  if (std::strchr(it->second.usage, ' ') == nullptr && !c.args.empty()) {
    fail_usage(name + " takes no arguments (got \"" + c.args[0] + "\")");
  }
  try {
    return it->second.run(c);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cnc: %s\n", e.what());
    return 1;
  }
}
