// The Python module `cnc`: LinuxCNC's `linuxcnc` module in shape
// (stat, command, error_channel, the same constants and attribute names
// where the meaning is the same) over the client library. It reads the
// shared segment and sends on a command channel of its own, as the CLI and
// the screen do; it never links the controller. Differences from LinuxCNC
// are in docs/connectivity.md.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <sys/stat.h>

#include "core/ini/ini_file.hpp"
#include "core/ipc/client.hpp"
#include "core/ipc/operator_commands.hpp"
#include "core/tooltable/tool_table.hpp"
#include "core/util/strings.hpp"

namespace py = pybind11;
using namespace cnc;
using ipc::Command;

namespace {

// LinuxCNC's constants (their values, so that scripts comparing numbers
// still work).
constexpr int RCS_DONE = 1, RCS_EXEC = 2, RCS_ERROR = 3;
constexpr int AUTO_RUN = 0, AUTO_PAUSE = 1, AUTO_RESUME = 2, AUTO_STEP = 3;
constexpr int JOG_STOP = 0, JOG_CONTINUOUS = 1, JOG_INCREMENT = 2, JOG_ABSOLUTE = 3;
constexpr int SPINDLE_FORWARD = 1, SPINDLE_REVERSE = -1, SPINDLE_OFF = 0, SPINDLE_INCREASE = 10,
              SPINDLE_DECREASE = 11, SPINDLE_CONSTANT = 12;
constexpr int NML_ERROR = 1, NML_TEXT = 2, NML_DISPLAY = 3, OPERATOR_ERROR = 11, OPERATOR_TEXT = 12,
              OPERATOR_DISPLAY = 13;

std::string instance_or_default(const std::optional<std::string>& instance) {
  return instance ? *instance : ipc::default_instance();
}

py::tuple pose_tuple(const Pose& p) {
  py::tuple t(kNumAxes);
  for (int a = 0; a < kNumAxes; ++a) t[static_cast<std::size_t>(a)] = p[a];
  return t;
}

template <typename T, std::size_t N>
py::tuple array_tuple(const T (&a)[N]) {
  py::tuple t(N);
  for (std::size_t i = 0; i < N; ++i) t[i] = a[i];
  return t;
}

int rcs_of(ipc::CommandState s) {
  switch (s) {
    case ipc::CommandState::Done: return RCS_DONE;
    case ipc::CommandState::Rejected: return RCS_ERROR;
    default: return RCS_EXEC;
  }
}

// stat: a copy of the status block, taken by poll().
class Stat {
 public:
  explicit Stat(const std::optional<std::string>& instance) : client_(instance_or_default(instance)) {}

  void poll() {
    s_ = client_.status();
    polled_ = true;
    load_tool_table();
  }
  const ipc::Status& s() const {
    if (!polled_) throw ipc::ClientError("stat: call poll() first");
    return s_;
  }
  py::tuple tool_table() const {
    s();
    std::vector<tooltable::Tool> tools = tools_ ? tools_->tools() : std::vector<tooltable::Tool>{};
    // Index 0 is the spindle, as LinuxCNC's tool_table[0].
    tooltable::Tool spindle = tools_ ? tools_->spindle() : tooltable::Tool{};
    if (spindle.is_empty() && s_.io.tool_in_spindle > 0 && tools_) {
      if (const auto i = tools_->find_tool(s_.io.tool_in_spindle)) spindle = tools_->at(*i);
    }
    tools.insert(tools.begin(), spindle);
    py::tuple t(tools.size());
    for (std::size_t i = 0; i < tools.size(); ++i) {
      const tooltable::Tool& tl = tools[i];
      py::dict d;
      d["id"] = tl.is_empty() ? -1 : tl.number;
      d["pocketno"] = tl.pocket;
      const char* names[kNumAxes] = {"xoffset", "yoffset", "zoffset", "aoffset", "boffset",
                                     "coffset", "uoffset", "voffset", "woffset"};
      for (int a = 0; a < kNumAxes; ++a) d[names[a]] = tl.offset[a];
      d["diameter"] = tl.diameter;
      d["frontangle"] = tl.front_angle;
      d["backangle"] = tl.back_angle;
      d["orientation"] = tl.orientation;
      d["comment"] = tl.comment;
      t[i] = d;
    }
    return t;
  }

 private:
  // The tool table is not in the status block: it is read from the INI's
  // [EMCIO]TOOL_TABLE file, again whenever the file changes.
  void load_tool_table() {
    const std::string ini_path = s_.health.ini_file.c_str();
    if (ini_path.empty()) return;
    try {
      if (ini_path != ini_path_) {
        ini_path_ = ini_path;
        const ini::IniFile ini = ini::IniFile::load(ini_path);
        const auto tt = ini.find("EMCIO", "TOOL_TABLE");
        table_path_ = tt ? ini.resolve_path(trim(*tt)).string() : "";
        random_ = parse_bool(ini.find("EMCIO", "RANDOM_TOOLCHANGER").value_or("0")).value_or(false);
        mtime_ = -1;
      }
      if (table_path_.empty()) return;
      struct stat st {};
      if (::stat(table_path_.c_str(), &st) != 0) return;
      const int64_t m = static_cast<int64_t>(st.st_mtim.tv_sec) * 1'000'000'000 + st.st_mtim.tv_nsec;
      if (m == mtime_) return;
      tools_ = tooltable::ToolTable::load(table_path_, random_ ? tooltable::ChangerKind::Random
                                                               : tooltable::ChangerKind::NonRandom);
      mtime_ = m;
    } catch (const std::exception& e) {
      throw ipc::ClientError(std::string("stat: tool table: ") + e.what());
    }
  }

  ipc::Client client_;
  ipc::Status s_{};
  bool polled_ = false;
  std::string ini_path_, table_path_;
  bool random_ = false;
  int64_t mtime_ = -1;
  std::optional<tooltable::ToolTable> tools_;
};

// command: every operator command. Each call sends the command and waits
// until the controller took it (accepted: running or done) or refused it:
// a refusal raises cnc.error with the controller's reason.
// wait_complete() waits until the last command has finished.
class Cmd {
 public:
  explicit Cmd(const std::optional<std::string>& instance) : client_(instance_or_default(instance)) {}

  void issue(const Command& c) {
    py::gil_scoped_release unlocked;
    last_ = client_.send(c);
    last_type_ = c.type;
    result_.reset();
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    for (;;) {
      const ipc::CommandResult r = client_.wait(last_, std::chrono::milliseconds(20));
      if (r.state == ipc::CommandState::Done || r.state == ipc::CommandState::Rejected) result_ = r;
      if (r.state == ipc::CommandState::Rejected) {
        throw ipc::ClientError(std::string(ipc::to_string(c.type)) + " rejected: " + r.reason.c_str());
      }
      if (r.state == ipc::CommandState::Done || r.state == ipc::CommandState::Executing) return;
      if (r.state == ipc::CommandState::None && !r.reason.empty()) {
        throw ipc::ClientError(std::string(ipc::to_string(c.type)) + ": " + r.reason.c_str());
      }
      if (std::chrono::steady_clock::now() > deadline) {
        throw ipc::ClientError(std::string(ipc::to_string(c.type)) + ": not taken by the controller within 10 s");
      }
    }
  }

  // RCS_DONE, or -1 on timeout (as LinuxCNC); raises when the command failed.
  int wait_complete(double timeout_s) {
    if (last_ == 0) return RCS_DONE;
    if (!result_) {
      py::gil_scoped_release unlocked;
      const ipc::CommandResult r =
          client_.wait(last_, std::chrono::milliseconds(static_cast<int64_t>(timeout_s * 1000)));
      if (r.state == ipc::CommandState::Done || r.state == ipc::CommandState::Rejected) result_ = r;
      else if (r.state == ipc::CommandState::None && !r.reason.empty()) {
        throw ipc::ClientError(std::string(ipc::to_string(last_type_)) + ": " + r.reason.c_str());
      }
    }
    if (!result_) return -1;
    if (result_->state == ipc::CommandState::Rejected) {
      throw ipc::ClientError(std::string(ipc::to_string(last_type_)) + " failed: " + result_->reason.c_str());
    }
    return RCS_DONE;
  }

  uint32_t serial() const { return last_; }

  // E-stop through the segment's E-stop word first (acted on in the servo
  // thread, needs no channel), then the task is told, as the CLI does.
  void estop() {
    const uint64_t req = client_.request_estop();
    issue(ipc::commands::set_state(ipc::TaskState::Estop));
    py::gil_scoped_release unlocked;
    if (client_.liveness(client_.status()).servo_age_ns >= 0 &&
        !client_.wait_estop_acknowledged(req, std::chrono::seconds(5))) {
      throw ipc::ClientError("E-stop requested, but motion did not acknowledge it within 5 s");
    }
  }

 private:
  ipc::Client client_;
  uint32_t last_ = 0;
  ipc::CommandType last_type_ = ipc::CommandType::None;
  std::optional<ipc::CommandResult> result_;
};

class ErrorChannel {
 public:
  explicit ErrorChannel(const std::optional<std::string>& instance) : client_(instance_or_default(instance)) {}
  // (kind, text) of the next message, or None. Kinds: an operator message
  // (from a client) is OPERATOR_*, one of the controller is NML_*.
  py::object poll() {
    Message m;
    if (!client_.next_message(m)) return py::none();
    const bool op = std::string_view(m.source.c_str()) == "operator";
    int kind = m.kind == MessageKind::Error ? NML_ERROR : m.kind == MessageKind::Text ? NML_TEXT : NML_DISPLAY;
    if (op) kind += 10;
    return py::make_tuple(kind, std::string(m.text.c_str()));
  }
  // As poll(), with the source ("motion", "interp", ...) and the time.
  py::object poll_full() {
    Message m;
    if (!client_.next_message(m)) return py::none();
    py::dict d;
    d["kind"] = to_string(m.kind);
    d["source"] = std::string(m.source.c_str());
    d["text"] = std::string(m.text.c_str());
    d["time"] = static_cast<double>(m.time_ns) * 1e-9;
    return d;
  }
  void rewind() { client_.rewind_messages(); }

 private:
  ipc::Client client_;
};

using S = const Stat&;
#define STAT(name, expr) def_property_readonly(name, [](S st) { const ipc::Status& s = st.s(); (void)s; return expr; })

py::dict joint_dict(const ipc::JointStatus& j) {
  py::dict d;
  d["jointType"] = j.type == 0 ? 1 : 2;  // LinuxCNC: 1 linear, 2 angular
  d["backlash"] = j.backlash;
  d["min_position_limit"] = j.min_position_limit;
  d["max_position_limit"] = j.max_position_limit;
  d["max_ferror"] = j.ferror;
  d["min_ferror"] = j.min_ferror;
  d["ferror_current"] = j.ferror_current;
  d["ferror_highmark"] = j.ferror_highmark;
  d["output"] = j.pos_cmd;
  d["input"] = j.pos_fb;
  d["velocity"] = j.velocity;
  d["inpos"] = static_cast<int>(j.inpos);
  d["homing"] = static_cast<int>(j.homing);
  d["homed"] = static_cast<int>(j.homed);
  d["fault"] = static_cast<int>(j.fault);
  d["enabled"] = static_cast<int>(j.enabled);
  d["min_soft_limit"] = static_cast<int>(j.min_soft_limit);
  d["max_soft_limit"] = static_cast<int>(j.max_soft_limit);
  d["min_hard_limit"] = static_cast<int>(j.min_hard_limit);
  d["max_hard_limit"] = static_cast<int>(j.max_hard_limit);
  d["override_limits"] = static_cast<int>(j.override_limits);
  return d;
}

py::dict spindle_dict(const ipc::SpindleStatus& sp) {
  py::dict d;
  d["speed"] = sp.speed;
  d["override"] = sp.override_scale;
  d["override_enabled"] = sp.override_enabled;
  d["direction"] = sp.direction;
  d["enabled"] = static_cast<int>(sp.enabled);
  d["brake"] = static_cast<int>(sp.brake);
  d["orient_state"] = sp.orient_state;
  d["orient_fault"] = sp.orient_fault;
  d["at_speed"] = sp.at_speed;          // extension
  d["speed_feedback"] = sp.speed_feedback;  // extension
  return d;
}

}  // namespace

PYBIND11_MODULE(cnc, m) {
  m.doc() = "Python interface of the CNC controller, in the shape of LinuxCNC's linuxcnc module";
  static py::exception<ipc::ClientError> error(m, "error");
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const ipc::ClientError& e) {
      error(e.what());
    } catch (const std::invalid_argument& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });

#define CONST(n, v) m.attr(n) = static_cast<int>(v)
  CONST("STATE_ESTOP", ipc::TaskState::Estop);
  CONST("STATE_ESTOP_RESET", ipc::TaskState::EstopReset);
  CONST("STATE_OFF", ipc::TaskState::Off);
  CONST("STATE_ON", ipc::TaskState::On);
  CONST("MODE_MANUAL", ipc::TaskMode::Manual);
  CONST("MODE_AUTO", ipc::TaskMode::Auto);
  CONST("MODE_MDI", ipc::TaskMode::Mdi);
  CONST("INTERP_IDLE", ipc::InterpState::Idle);
  CONST("INTERP_READING", ipc::InterpState::Reading);
  CONST("INTERP_PAUSED", ipc::InterpState::Paused);
  CONST("INTERP_WAITING", ipc::InterpState::Waiting);
  CONST("EXEC_ERROR", ipc::ExecState::Error);
  CONST("EXEC_DONE", ipc::ExecState::Done);
  CONST("EXEC_WAITING_FOR_MOTION", ipc::ExecState::WaitingForMotion);
  CONST("EXEC_WAITING_FOR_MOTION_QUEUE", ipc::ExecState::WaitingForMotionQueue);
  CONST("EXEC_WAITING_FOR_IO", ipc::ExecState::WaitingForIo);
  CONST("EXEC_WAITING_FOR_MOTION_AND_IO", ipc::ExecState::WaitingForMotionAndIo);
  CONST("EXEC_WAITING_FOR_DELAY", ipc::ExecState::WaitingForDelay);
  CONST("EXEC_WAITING_FOR_SYSTEM_CMD", ipc::ExecState::WaitingForSystemCmd);
  CONST("EXEC_WAITING_FOR_SPINDLE_ORIENTED", ipc::ExecState::WaitingForSpindleOriented);
  CONST("TRAJ_MODE_FREE", ipc::MotionMode::Free);
  CONST("TRAJ_MODE_COORD", ipc::MotionMode::Coord);
  CONST("TRAJ_MODE_TELEOP", ipc::MotionMode::Teleop);
  CONST("RCS_DONE", RCS_DONE);
  CONST("RCS_EXEC", RCS_EXEC);
  CONST("RCS_ERROR", RCS_ERROR);
  CONST("AUTO_RUN", AUTO_RUN);
  CONST("AUTO_PAUSE", AUTO_PAUSE);
  CONST("AUTO_RESUME", AUTO_RESUME);
  CONST("AUTO_STEP", AUTO_STEP);
  CONST("JOG_STOP", JOG_STOP);
  CONST("JOG_CONTINUOUS", JOG_CONTINUOUS);
  CONST("JOG_INCREMENT", JOG_INCREMENT);
  CONST("JOG_ABSOLUTE", JOG_ABSOLUTE);
  CONST("SPINDLE_FORWARD", SPINDLE_FORWARD);
  CONST("SPINDLE_REVERSE", SPINDLE_REVERSE);
  CONST("SPINDLE_OFF", SPINDLE_OFF);
  CONST("SPINDLE_INCREASE", SPINDLE_INCREASE);
  CONST("SPINDLE_DECREASE", SPINDLE_DECREASE);
  CONST("SPINDLE_CONSTANT", SPINDLE_CONSTANT);
  CONST("FLOOD_ON", 1);
  CONST("FLOOD_OFF", 0);
  CONST("MIST_ON", 1);
  CONST("MIST_OFF", 0);
  CONST("BRAKE_ENGAGE", 1);
  CONST("BRAKE_RELEASE", 0);
  CONST("NML_ERROR", NML_ERROR);
  CONST("NML_TEXT", NML_TEXT);
  CONST("NML_DISPLAY", NML_DISPLAY);
  CONST("OPERATOR_ERROR", OPERATOR_ERROR);
  CONST("OPERATOR_TEXT", OPERATOR_TEXT);
  CONST("OPERATOR_DISPLAY", OPERATOR_DISPLAY);
#undef CONST

  py::class_<Stat>(m, "stat")
      .def(py::init<std::optional<std::string>>(), py::arg("instance") = py::none())
      .def("poll", &Stat::poll, "copy the controller's status (raises cnc.error when it is gone)")
      // task
      .STAT("task_state", static_cast<int>(s.task.state))
      .STAT("task_mode", static_cast<int>(s.task.mode))
      .STAT("interp_state", static_cast<int>(s.task.interp_state))
      .STAT("exec_state", static_cast<int>(s.task.exec_state))
      .STAT("state", rcs_of(s.echo.state))
      .STAT("echo_serial_number", s.echo.serial)
      .STAT("estop", static_cast<int>(s.task.state == ipc::TaskState::Estop))
      .STAT("task_paused", static_cast<int>(s.task.paused))
      .STAT("file", std::string(s.task.file.c_str()))
      .STAT("command", std::string(s.task.command.c_str()))
      .STAT("current_line", s.task.current_line)
      .STAT("read_line", s.task.read_line)
      .STAT("motion_line", s.motion.motion_line)
      .STAT("program_units", s.task.program_units)
      .STAT("g5x_index", s.task.g5x_index)
      .STAT("g5x_offset", pose_tuple(s.task.g5x_offset))
      .STAT("g92_offset", pose_tuple(s.task.g92_offset))
      .STAT("rotation_xy", s.task.rotation_xy)
      .STAT("tool_offset", pose_tuple(s.task.tool_offset))
      .STAT("gcodes", array_tuple(s.task.active_gcodes))
      .STAT("mcodes", array_tuple(s.task.active_mcodes))
      .STAT("settings", array_tuple(s.task.active_settings))
      .STAT("optional_stop", static_cast<int>(s.task.optional_stop))
      .STAT("block_delete", static_cast<int>(s.task.block_delete))
      .STAT("delay_left", s.task.delay_left)
      .STAT("queued_mdi_commands", s.task.queued_mdi)
      .STAT("ini_filename", std::string(s.health.ini_file.c_str()))
      // motion
      .STAT("enabled", s.motion.enabled)
      .STAT("paused", s.motion.paused)
      .STAT("inpos", s.motion.inpos)
      .STAT("queue", s.motion.queue)
      .STAT("queue_full", s.motion.queue_full)
      .STAT("motion_mode", static_cast<int>(s.motion.mode))
      .STAT("id", s.motion.motion_id)
      .STAT("position", pose_tuple(s.motion.position))
      .STAT("actual_position", pose_tuple(s.motion.actual_position))
      .STAT("dtg", pose_tuple(s.motion.dtg))
      .STAT("distance_to_go", s.motion.distance_to_go)
      .STAT("current_vel", s.motion.current_vel)
      .STAT("feedrate", s.motion.feed_scale)
      .STAT("rapidrate", s.motion.rapid_scale)
      .STAT("max_velocity", s.motion.max_velocity)
      .STAT("feed_override_enabled", s.motion.feed_override_enabled)
      .STAT("adaptive_feed_enabled", s.motion.adaptive_feed_enabled)
      .STAT("feed_hold_enabled", s.motion.feed_hold_enabled)
      .STAT("probing", s.motion.probing)
      .STAT("probe_tripped", s.motion.probe_tripped)
      .STAT("probe_val", static_cast<int>(s.motion.probe_input))
      .STAT("probed_position", pose_tuple(s.motion.probed_position))
      .STAT("axis_mask", s.motion.axis_mask)
      .STAT("joints", s.motion.joints)
      .STAT("spindles", s.motion.spindles)
      .STAT("kinematics_type", static_cast<int>(s.motion.kinematics_type))
      .STAT("linear_units", s.motion.linear_units)
      .STAT("angular_units", s.motion.angular_units)
      .STAT("cycle_time", s.motion.cycle_time_s)
      .STAT("joint_position", [&] {
        py::tuple t(kMaxJoints);
        for (int j = 0; j < kMaxJoints; ++j) t[static_cast<std::size_t>(j)] = s.joints[j].pos_cmd;
        return t;
      }())
      .STAT("joint_actual_position", [&] {
        py::tuple t(kMaxJoints);
        for (int j = 0; j < kMaxJoints; ++j) t[static_cast<std::size_t>(j)] = s.joints[j].pos_fb;
        return t;
      }())
      .STAT("homed", [&] {
        py::tuple t(kMaxJoints);
        for (int j = 0; j < kMaxJoints; ++j) t[static_cast<std::size_t>(j)] = static_cast<int>(s.joints[j].homed);
        return t;
      }())
      .STAT("joint", [&] {
        py::tuple t(kMaxJoints);
        for (int j = 0; j < kMaxJoints; ++j) t[static_cast<std::size_t>(j)] = joint_dict(s.joints[j]);
        return t;
      }())
      .STAT("axis", [&] {
        py::tuple t(kNumAxes);
        for (int a = 0; a < kNumAxes; ++a) {
          py::dict d;
          d["velocity"] = s.axes[a].velocity;
          d["min_position_limit"] = s.axes[a].min_position_limit;
          d["max_position_limit"] = s.axes[a].max_position_limit;
          t[static_cast<std::size_t>(a)] = d;
        }
        return t;
      }())
      .STAT("spindle", [&] {
        py::tuple t(ipc::kMaxSpindles);
        for (int i = 0; i < ipc::kMaxSpindles; ++i) t[static_cast<std::size_t>(i)] = spindle_dict(s.spindles[i]);
        return t;
      }())
      // io
      .STAT("tool_in_spindle", s.io.tool_in_spindle)
      .STAT("pocket_prepped", s.io.pocket_prepped)
      .STAT("flood", static_cast<int>(s.io.flood))
      .STAT("mist", static_cast<int>(s.io.mist))
      .STAT("lube", static_cast<int>(s.io.lube))
      .STAT("lube_level", static_cast<int>(s.io.lube_level_ok))
      .def_property_readonly("tool_table", &Stat::tool_table);

  namespace c = ipc::commands;
  py::class_<Cmd>(m, "command")
      .def(py::init<std::optional<std::string>>(), py::arg("instance") = py::none())
      .def_property_readonly("serial", &Cmd::serial)
      .def("wait_complete", &Cmd::wait_complete, py::arg("timeout") = 5.0)
      .def("state", [](Cmd& k, int st) {
        if (st < 1 || st > 4) throw std::invalid_argument("state: expected STATE_ESTOP .. STATE_ON, got " + std::to_string(st));
        if (st == static_cast<int>(ipc::TaskState::Estop)) return k.estop();
        k.issue(c::set_state(static_cast<ipc::TaskState>(st)));
      })
      .def("mode", [](Cmd& k, int md) {
        if (md < 1 || md > 3) throw std::invalid_argument("mode: expected MODE_MANUAL, MODE_AUTO or MODE_MDI, got " + std::to_string(md));
        k.issue(c::set_mode(static_cast<ipc::TaskMode>(md)));
      })
      .def("abort", [](Cmd& k) { k.issue(c::abort()); })
      .def("mdi", [](Cmd& k, const std::string& line) { k.issue(c::mdi(line)); })
      .def("program_open", [](Cmd& k, const std::string& path) {
        k.issue(c::open(std::filesystem::absolute(path).lexically_normal().string()));
      })
      .def("program_close", [](Cmd& k) { k.issue(c::close()); })
      .def("auto", [](Cmd& k, int what, int line) {
        switch (what) {
          case AUTO_RUN: return k.issue(c::run(line));
          case AUTO_PAUSE: return k.issue(c::pause());
          case AUTO_RESUME: return k.issue(c::resume());
          case AUTO_STEP: return k.issue(c::step());
          default: throw std::invalid_argument("auto: expected AUTO_RUN, AUTO_PAUSE, AUTO_RESUME or AUTO_STEP");
        }
      }, py::arg("what"), py::arg("line") = 0)
      .def("home", [](Cmd& k, int j) { k.issue(c::home(j)); })
      .def("unhome", [](Cmd& k, int j) { k.issue(c::unhome(j)); })
      .def("override_limits", [](Cmd& k) { k.issue(c::override_limits()); })
      .def("jog", [](Cmd& k, int what, bool joint, int index, double velocity, double distance) {
        switch (what) {
          case JOG_STOP: return k.issue(c::jog_stop(index, joint));
          case JOG_CONTINUOUS: return k.issue(c::jog_continuous(index, joint, velocity));
          case JOG_INCREMENT: return k.issue(c::jog_increment(index, joint, velocity, distance));
          case JOG_ABSOLUTE: return k.issue(c::jog_absolute(index, joint, velocity, distance));
          default: throw std::invalid_argument("jog: expected JOG_STOP, JOG_CONTINUOUS, JOG_INCREMENT or JOG_ABSOLUTE");
        }
      }, py::arg("what"), py::arg("joint_mode"), py::arg("index"), py::arg("velocity") = 0.0, py::arg("distance") = 0.0)
      .def("feedrate", [](Cmd& k, double r) { k.issue(c::feed_override(r)); })
      .def("rapidrate", [](Cmd& k, double r) { k.issue(c::rapid_override(r)); })
      .def("maxvel", [](Cmd& k, double v) { k.issue(c::max_velocity(v)); })
      .def("spindleoverride", [](Cmd& k, double r, int sp) { k.issue(c::spindle_override(r, sp)); },
           py::arg("scale"), py::arg("spindle") = 0)
      .def("spindle", [](Cmd& k, int dir, double speed, int sp) {
        switch (dir) {
          case SPINDLE_FORWARD: return k.issue(c::spindle_on(std::fabs(speed), sp));
          case SPINDLE_REVERSE: return k.issue(c::spindle_on(-std::fabs(speed), sp));
          case SPINDLE_OFF: return k.issue(c::spindle_off(sp));
          case SPINDLE_INCREASE: return k.issue(c::spindle_faster(sp));
          case SPINDLE_DECREASE: return k.issue(c::spindle_slower(sp));
          case SPINDLE_CONSTANT: return k.issue([&] { Command x = ipc::make_command(ipc::CommandType::SpindleConstant); x.i[0] = sp; return x; }());
          default: throw std::invalid_argument("spindle: expected SPINDLE_FORWARD, _REVERSE, _OFF, _INCREASE, _DECREASE or _CONSTANT");
        }
      }, py::arg("direction"), py::arg("speed") = 0.0, py::arg("spindle") = 0)
      .def("brake", [](Cmd& k, int on, int sp) { k.issue(c::spindle_brake(on != 0, sp)); }, py::arg("engage"), py::arg("spindle") = 0)
      .def("flood", [](Cmd& k, int on) { k.issue(c::flood(on != 0)); })
      .def("mist", [](Cmd& k, int on) { k.issue(c::mist(on != 0)); })
      .def("lube", [](Cmd& k, int on) { k.issue(c::lube(on != 0)); })
      .def("set_optional_stop", [](Cmd& k, bool on) { k.issue(c::optional_stop(on)); })
      .def("set_block_delete", [](Cmd& k, bool on) { k.issue(c::block_delete(on)); })
      .def("teleop_enable", [](Cmd& k, bool on) { k.issue(c::teleop_enable(on)); })
      .def("set_feed_override", [](Cmd& k, bool on) { k.issue(c::feed_override_enable(on)); })
      .def("load_tool_table", [](Cmd& k) { k.issue(c::tool_load_table()); })
      .def("set_tool_number", [](Cmd& k, int t) { k.issue(c::tool_set_number(t)); })
      .def("tool_offset", [](Cmd& k, int tool, double z, double x, double diameter, double front, double back, int orient) {
        Pose p;
        p[0] = x;
        p[2] = z;
        k.issue(c::tool_set_offset(tool, -1, p, diameter, front, back, orient, ""));
      }, py::arg("toolno"), py::arg("z_offset"), py::arg("x_offset") = 0.0, py::arg("diameter") = 0.0,
         py::arg("frontangle") = 0.0, py::arg("backangle") = 0.0, py::arg("orientation") = 0)
      .def("set_work_offset", [](Cmd& k, int index, const std::vector<double>& offsets, double rotation) {
        if (offsets.size() > static_cast<std::size_t>(kNumAxes)) throw std::invalid_argument("set_work_offset: at most 9 offsets (X..W)");
        Pose p;
        for (std::size_t a = 0; a < offsets.size(); ++a) p[static_cast<int>(a)] = offsets[a];
        k.issue(c::set_work_offset(index, p, rotation));
      }, py::arg("index"), py::arg("offsets"), py::arg("rotation") = 0.0)
      .def("reset_interpreter", [](Cmd& k) { k.issue(ipc::make_command(ipc::CommandType::TaskPlanInit)); })
      .def("task_plan_synch", [](Cmd& k) { k.issue(ipc::make_command(ipc::CommandType::TaskPlanSynch)); })
      .def("set_digital_output", [](Cmd& k, int i, bool v) { k.issue(c::set_digital_output(i, v)); })
      .def("set_analog_output", [](Cmd& k, int i, double v) { k.issue(c::set_analog_output(i, v)); })
      .def("error_msg", [](Cmd& k, const std::string& t) { k.issue(c::operator_error(t)); })
      .def("text_msg", [](Cmd& k, const std::string& t) { k.issue(c::operator_text(t)); })
      .def("display_msg", [](Cmd& k, const std::string& t) { k.issue(c::operator_display(t)); });

  py::class_<ErrorChannel>(m, "error_channel")
      .def(py::init<std::optional<std::string>>(), py::arg("instance") = py::none())
      .def("poll", &ErrorChannel::poll)
      .def("poll_full", &ErrorChannel::poll_full)
      .def("rewind", &ErrorChannel::rewind);
}
