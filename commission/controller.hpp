// The running controller as the commissioning steps see it: the `cnc` and
// `halcmd` programs of the same build (bin_dir) on the instance of the
// environment (CNC_INSTANCE), i.e. the shared segment and the halcmd
// socket. Motions of commissioning go through here, each limited in
// travel, speed and time; whatever happens, the machine is switched off
// (drives disabled) at the end, and a failure says why. Non-realtime.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "commission/state.hpp"

namespace cnc::commission {

class Controller {
 public:
  explicit Controller(std::filesystem::path bin_dir) : bin_(std::move(bin_dir)) {}
  // Runs `cnc <args>`; its standard output. Throws std::runtime_error with
  // the command and its output when it fails.
  std::string cnc(const std::vector<std::string>& args) const;
  // Runs `halcmd <args>`; its standard output (throws as cnc()).
  std::string halcmd(const std::vector<std::string>& args) const { return run(bin_ / "halcmd", args); }
  // `halcmd getp <name>` as a number.
  double getp(const std::string& name) const;
  // A joint's motor position feedback (machine units) from the status.
  double motor_position(int joint) const;
  bool estop_chain_ok() const;
  // The servo thread's period (s) from the status; 1 ms if it shows none.
  double servo_period_s() const;

 private:
  std::string run(const std::filesystem::path& program, const std::vector<std::string>& args) const;
  std::filesystem::path bin_;
};

// A controller this program brought up itself: `cncd` on `ini` (its
// output to `log`), on the instance of the environment, waited for until
// it answers (at most 30 s; else it is stopped and the constructor throws
// with the end of its log). The destructor shuts it down unless detached.
class ControllerProcess {
 public:
  ControllerProcess(const std::filesystem::path& bin_dir, const std::filesystem::path& ini,
                    const std::filesystem::path& log);
  ~ControllerProcess();
  ControllerProcess(const ControllerProcess&) = delete;
  ControllerProcess& operator=(const ControllerProcess&) = delete;
  // `cnc shutdown`, then waits (10 s, then SIGTERM); cncd's exit status,
  // or -1 when it had to be killed.
  int stop();
  // Leaves it running after this object (a command-line bring-up).
  void detach() noexcept { pid_ = -1; }
  int pid() const noexcept { return pid_; }

 private:
  std::filesystem::path bin_;
  int pid_ = -1;
};

// Asks a running commissioning motion to stop (jog stop, machine off, an
// error saying it was aborted). Async-signal-safe: the command-line program
// calls it from its SIGINT and SIGTERM handlers.
void request_abort() noexcept;
// Whether request_abort() was called since the last clear_abort().
bool abort_requested() noexcept;
void clear_abort() noexcept;

// After a commissioning motion failed: switches the machine off (after
// `cnc abort` when `abort_program`) and says in what state it was left:
// "; the machine is off again, the drives disabled", "; the machine is in
// E-stop, the drives disabled" (the controller's own stop came first) or
// that switching off failed too and E-stop must be pressed. Never throws.
std::string switch_off_after_failure(const Controller& c, bool abort_program = false) noexcept;

// Homes every joint not homed yet (switched on, manual mode, `cnc home
// all`) and waits until all are, at most `timeout_s`. Throws
// std::runtime_error starting with `who` on the time limit or
// request_abort(); the caller switches the machine off.
void home_all(const Controller& c, const std::string& who, double timeout_s = 120);

struct JogResult {
  double commanded_mm = 0;
  double feedback_mm = 0;   // motor feedback after - before
  bool limited = false;     // the distance asked for was cut to direction_test_travel_limit()
  std::optional<double> gantry_feedback_mm;  // a gantry pair: its second drive's joint, jogged with the first
};

// The direction test's motion: joint `a.joint` jogs `distance_mm` (at most
// direction_test_travel_limit(a): kFirstTestTravel until a dial reading
// checked the scaling, then kMaxTestTravel; sign = direction) at `velocity`
// (at most kMaxTestVelocity) in free (joint) mode, switched on for the move and off
// afterwards, stopped after a time limit (twice the travel time + 3 s).
// Refuses when the E-stop chain is open. Throws std::runtime_error saying
// why it stopped (time limit, request_abort(), a failing command). A
// gantry pair's two joints are jogged at once by the same distance (the
// shorter limit of the two), so the pair stays as square as it stood
// while each drive's own travel is measured.
JogResult direction_jog(const Controller& c, const Axis& a, double distance_mm, double velocity);

}  // namespace cnc::commission
