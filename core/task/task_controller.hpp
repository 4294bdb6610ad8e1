// The task controller (the manual's 3.10 and chapter 4's TASK group): the
// E-stop / machine-on state machine, the MANUAL / AUTO / MDI modes, program
// execution with the interpreter's read-ahead synchronised where it must
// wait, MDI with [MDI_COMMAND_LIST] macros, run from line, and every
// operator command of the command channel. It runs in the controller's
// task cycle and talks to motion and I/O through their non-realtime APIs.
#pragma once

#include <array>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/interp/interp.hpp"
#include "core/interp/python_host.hpp"
#include "core/io/io_controller.hpp"
#include "core/ipc/service.hpp"
#include "core/motion/motion_component.hpp"
#include "core/task/task_canon.hpp"
#include "core/util/messages.hpp"

namespace cnc::task {

struct TaskConfig {
  std::vector<std::string> mdi_macros;   // [MDI_COMMAND_LIST]MDI_COMMAND_MACROn
  int max_queued_mdi = 16;
  std::size_t readahead_items = 2000;    // execution-list depth the interpreter may run ahead
  std::string on_abort_command;          // [RS274NGC]ON_ABORT_COMMAND (an MDI line)
  std::array<double, ipc::kMaxSpindles> spindle_increment{};  // [SPINDLE_n]INCREMENT, rpm per faster/slower
  static TaskConfig from_ini(const ini::IniFile& ini);
};

class TaskController : public ipc::ControllerService {
 public:
  TaskController(const ini::IniFile& ini, hal::Hal& hal, motion::MotionComponent& motion, io::IoController& io,
                 MessageQueue& messages);
  ~TaskController() override;

  int service_order() const noexcept override { return 30; }
  bool handle_command(const ipc::Command& cmd, ipc::CommandReporter& reporter) override;
  void update(int64_t now_ns) override;
  void on_controller_shutdown() override;
  void contribute_status(ipc::Status& status) override;
  bool is_safe_to_stop() const override;

  ipc::TaskState state() const noexcept { return state_; }
  ipc::TaskMode mode() const noexcept { return mode_; }
  ipc::InterpState interp_state() const noexcept { return interp_state_; }

 private:
  // A command answered later: `check` runs every cycle until it returns
  // true, after reporting through `done`.
  struct Waiter {
    ipc::Command cmd;
    std::function<bool()> check;
  };

  // command handlers; return a rejection reason or empty
  std::string set_state(const ipc::Command& c);
  std::string set_mode(const ipc::Command& c);
  std::string jog(const ipc::Command& c);
  std::string home(const ipc::Command& c);
  std::string program_open(const std::string& path);
  std::string program_run(const ipc::Command& c);
  std::string mdi(const ipc::Command& c);
  std::string run_from_line_preview(const ipc::Command& c);
  std::string set_parameter(const ipc::Command& c);
  std::string tool_command(const ipc::Command& c);

  uint64_t send(motion::MotionCommand c);
  // Waits for the answer to a motion command, then reports it.
  void answer_after(const ipc::Command& cmd, uint64_t serial, std::function<bool()> also_wait = nullptr);
  bool motion_answered(uint64_t serial) const { return serial <= last_answered_; }
  const motion::MotionResult* motion_result(uint64_t serial) const;
  bool motion_idle() const;
  void ensure_motion_mode(ipc::MotionMode m);

  void stop_motion();  // abort, disable, forget VOLATILE_HOME homes
  void enter_estop(const std::string& why);
  // Catches up with what motion did on its own in the servo thread (an
  // E-stop latch, a fault) and notices motion that stopped running.
  void check_safety(int64_t now_ns);
  void report_motion_fault(int64_t now_ns);
  void machine_off(const std::string& why);
  void abort_all(const std::string& why, bool quiet = false);
  void program_error(const std::string& what);
  void program_finished();
  // The interpreter runs stepwise: each of these reads and executes for at
  // most kReadBudgetNs per task cycle (read() itself returns every few
  // hundred lines), so a long or endless computation never stalls the
  // cycle; the interpreter's MAX_BLOCKS_WITHOUT_OUTPUT ends an endless one.
  void run_interpreter();
  void run_mdi();
  void synch_interpreter();  // the machine is at rest: the interpreter re-reads it
  void execute_items(int64_t now_ns);
  // Tags the items the block just executed added (items_[from..]) with the
  // interpreter's modal state after it (tp::StateTag).
  void tag_new_items(std::size_t from, int line);
  bool execute_item(Item& it, int64_t now_ns);  // true: done, pop it
  void start_mdi_line(const std::string& line, const ipc::Command& cmd);
  void pause(bool operator_request);
  void resume();
  // Run from line: executes the lines before the target with motion
  // suppressed (stepwise, within the cycle's budget), then queues what
  // restores the machine state there. True once it is done and the program
  // reads on; false while it goes on or after it failed.
  struct Reconstruction;
  bool reconstruct_step(int64_t deadline);
  void reconstruction_failed(const std::string& what);
  void finish_reconstruction();
  struct PreviewJob;
  bool preview_step(const ipc::Command& c, PreviewJob& job);  // true once `c` is answered
  void post(MessageKind kind, const std::string& text);
  // Writes the parameter file if it changed; empty, or the reason it could
  // not be written (also posted as an error).
  std::string save_parameters();
  // The path limits motion has in force, into a canon's view of the machine.
  void view_limits(MachineView& view) const;
  // Says on the message channel when a spindle's speed is held at one of
  // its limits (once each time it starts to be).
  void report_spindle_limits();
  // Says when a jog asks for more than the limit in force (motion clamps it).
  void report_jog_limit(const motion::MotionCommand& m);
  bool machine_homed() const;
  double read_input(int index, bool digital) const;

  const ini::IniFile& ini_;
  hal::Hal& hal_;
  motion::MotionComponent& motion_;
  io::IoController& io_;
  MessageQueue& messages_;
  TaskConfig cfg_;
  CanonConfig canon_cfg_;  // [TRAJ]LINEAR_UNITS, [EMCIO]TOOL_CHANGE_*: read once
  ipc::CommandReporter* reporter_ = nullptr;

  ipc::TaskState state_ = ipc::TaskState::Estop;
  ipc::TaskMode mode_ = ipc::TaskMode::Manual;
  ipc::InterpState interp_state_ = ipc::InterpState::Idle;
  ipc::ExecState exec_state_ = ipc::ExecState::Done;
  bool optional_stop_ = false;
  bool block_delete_ = false;
  bool paused_ = false;
  bool stepping_ = false;
  bool program_ended_ = false;
  bool running_mdi_ = false;
  bool mdi_reading_ = false;       // the MDI line, or a subroutine it called, has lines left to read
  bool mdi_line_started_ = false;  // the interpreter took the MDI line (read(line) done)

  motion::MotionStatus ms_;
  uint64_t last_submitted_ = 0;
  uint64_t last_answered_ = 0;
  std::map<uint64_t, motion::MotionResult> results_;
  std::vector<Waiter> waiters_;

  std::deque<Item> items_;
  MachineView view_;
  std::unique_ptr<TaskCanon> canon_;
  std::unique_ptr<interp::Interpreter> interp_;
  interp::Config interp_config_;  // without its script host: each interpreter gets its own
  interp::PythonSettings python_;  // [PYTHON]
  // An interpreter on `canon` with interp_config_ and a Python host of its own.
  std::unique_ptr<interp::Interpreter> make_interpreter(interp::Canon& canon) const;
  std::string file_;
  int total_lines_ = 0;
  int read_line_ = 0;
  int current_line_ = 0;
  bool waiting_synch_ = false;
  std::deque<std::pair<ipc::Command, std::string>> mdi_queue_;
  ipc::Command mdi_current_;
  std::string mdi_text_;
  int64_t program_started_ns_ = 0;
  int64_t program_elapsed_ns_ = 0;
  int64_t blocks_ = 0;
  int errors_ = 0;
  // Tag of the last item given to motion or executed; with motion at rest
  // everything given to it ran, so this is the executing line's state.
  tp::StateTag executed_tag_;
  // items in progress
  bool item_started_ = false;
  int64_t item_started_ns_ = 0;
  int user_m_pid_ = 0;
  // run from line
  std::shared_ptr<Reconstruction> reconstruct_;  // shared with the run command's waiter
  int run_from_line_ = 0;
  Pose run_from_start_;
  bool was_enabled_ = false;
  // A fault that disabled motion, said once the drive layer explained it
  // (its fault text) or after a short wait.
  struct FaultReport {
    bool pending = false;
    int64_t since_ns = 0;
    bool program = false;      // a program was running
    bool mdi = false;          // an MDI command was running
    int line = 0;
    std::string reason;        // motion's
    int joint = -1, spindle = -1;
  } fault_report_;
  // The drive panel as last contributed to the status (drive names, fault texts).
  std::array<ipc::DriveStatus, kMaxJoints + 1> drives_{};
  std::array<bool, ipc::kMaxSpindles> spindle_limited_{};  // last reported: held at a limit
  uint32_t spindle_timeouts_seen_ = 0;  // motion's at-speed timeouts already acted on
  uint32_t overrun_holds_seen_ = 0;  // motion's OVERRUN_ACTION = HOLD pauses already adopted
};

}  // namespace cnc::task
