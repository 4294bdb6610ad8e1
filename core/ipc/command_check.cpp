#include "core/ipc/command_check.hpp"

#include <cmath>
#include <cstdio>

#include "core/ipc/status.hpp"
#include "core/util/pose.hpp"

namespace cnc::ipc {
namespace {

// Collects the first failure; later checks are skipped.
class Checker {
 public:
  explicit Checker(const Command& c) : c_(c) {}

  Checker& in(int slot, const char* what, int lo, int hi) {
    const int v = c_.i[slot];
    if (why_.empty() && (v < lo || v > hi)) {
      why_ = std::string(what) + " " + std::to_string(v) + " is out of range (expected " + std::to_string(lo) +
             " to " + std::to_string(hi) + ")";
    }
    return *this;
  }
  Checker& flag(int slot, const char* what) { return in(slot, what, 0, 1); }
  Checker& real(int slot, const char* what, double lo, double hi) {
    const double v = c_.d[slot];
    if (!why_.empty()) return *this;
    if (!std::isfinite(v)) {
      why_ = std::string(what) + " is not a finite number";
    } else if (v < lo || v > hi) {
      char buf[160];
      std::snprintf(buf, sizeof buf, "%s %g is out of range (expected %g to %g)", what, v, lo, hi);
      why_ = buf;
    }
    return *this;
  }
  Checker& reals(int from, int to, const char* what, double bound) {
    for (int k = from; k <= to; ++k) real(k, what, -bound, bound);
    return *this;
  }
  // i[0] is a joint when i[1] is 1, an axis when it is 0.
  Checker& joint_or_axis() {
    flag(1, "joint/axis selector");
    return c_.i[1] == 1 ? in(0, "joint", 0, kMaxJoints - 1) : in(0, "axis", 0, kNumAxes - 1);
  }
  std::string why() const { return why_; }

 private:
  const Command& c_;
  std::string why_;
};

}  // namespace

std::string check_arguments(const Command& c) {
  Checker k(c);
  const double L = kMaxLinearArgument;
  switch (c.type) {
    case CommandType::TaskSetState: k.in(0, "task state", 1, 4); break;
    case CommandType::TaskSetMode: k.in(0, "task mode", 1, 3); break;
    case CommandType::TaskPlanRun: k.in(0, "start line", 0, 100'000'000); break;
    case CommandType::TaskPlanRunPreview: k.in(0, "line", 1, 100'000'000); break;
    case CommandType::TaskPlanExecute: k.in(0, "macro", -1, 999); break;
    case CommandType::TaskPlanSetOptionalStop:
    case CommandType::TaskPlanSetBlockDelete:
    case CommandType::TrajSetTeleopEnable:
    case CommandType::TrajSetFeedHoldEnable:
    case CommandType::TrajSetFeedOverrideEnable:
    case CommandType::TrajSetAdaptiveFeedEnable: k.flag(0, "on/off value"); break;
    case CommandType::TrajSetScale:
    case CommandType::TrajSetRapidScale: k.real(0, "override", 0, kMaxOverrideScale); break;
    case CommandType::TrajSetMaxVelocity: k.real(0, "velocity", 0, L); break;
    case CommandType::MotionSetDigitalOutput:
      k.in(0, "output", 0, kMaxMotionIo - 1).flag(1, "output value").flag(2, "timing");
      break;
    case CommandType::MotionSetAnalogOutput:
      k.in(0, "output", 0, kMaxMotionIo - 1).flag(2, "timing").real(0, "output value", -L, L);
      break;
    case CommandType::JogCont: k.joint_or_axis().real(0, "velocity", -L, L); break;
    case CommandType::JogIncr: k.joint_or_axis().real(0, "velocity", 0, L).real(1, "distance", -L, L); break;
    case CommandType::JogAbs: k.joint_or_axis().real(0, "velocity", 0, L).real(1, "position", -L, L); break;
    case CommandType::JogStop: k.joint_or_axis(); break;
    case CommandType::JointHome:
    case CommandType::JointOverrideLimits: k.in(0, "joint", -1, kMaxJoints - 1); break;
    case CommandType::JointUnhome: k.in(0, "joint", -2, kMaxJoints - 1); break;
    case CommandType::JointActivate:
    case CommandType::JointDeactivate: k.in(0, "joint", 0, kMaxJoints - 1); break;
    case CommandType::JointLoadComp: k.in(0, "joint", 0, kMaxJoints - 1).in(1, "compensation file type", 0, 1); break;
    case CommandType::SetParameter: k.in(0, "index", 0, kMaxJoints - 1).real(0, "value", -1e12, 1e12); break;
    case CommandType::SpindleOn: k.in(0, "spindle", 0, kMaxSpindles - 1).real(0, "speed (rpm)", -kMaxSpindleRpm, kMaxSpindleRpm); break;
    case CommandType::SpindleOff:
    case CommandType::SpindleIncrease:
    case CommandType::SpindleDecrease:
    case CommandType::SpindleConstant:
    case CommandType::SpindleBrakeRelease:
    case CommandType::SpindleBrakeEngage: k.in(0, "spindle", 0, kMaxSpindles - 1); break;
    case CommandType::SpindleOrient:
      k.in(0, "spindle", 0, kMaxSpindles - 1).in(1, "orient mode", 0, 2).real(0, "angle", -360, 360);
      break;
    case CommandType::SpindleOverride: k.in(0, "spindle", 0, kMaxSpindles - 1).real(0, "override", 0, kMaxOverrideScale); break;
    case CommandType::ToolSetOffset:
      k.in(0, "tool", 0, 99'999'999).in(1, "pocket", -1, 99'999'999).in(2, "orientation", 0, 9);
      k.reals(0, 9, "offset", L).reals(10, 11, "angle", 360);
      break;
    case CommandType::ToolSetNumber: k.in(0, "tool", 0, 99'999'999); break;
    case CommandType::ToolDelete: k.in(0, "tool", 1, 99'999'999); break;
    case CommandType::SetWorkOffset: k.in(0, "coordinate system", 0, 9).reals(0, 8, "offset", L).real(9, "rotation", -360, 360); break;
    case CommandType::SimInject: k.real(0, "value", -1e12, 1e12); break;
    case CommandType::AlarmAcknowledge: k.in(0, "alarm id", 0, 2'000'000'000); break;
    default: break;
  }
  return k.why();
}

}  // namespace cnc::ipc
