// One entry of the task controller's execution list (LinuxCNC's interp
// list): what the interpreter asked for, in program order, waiting to be
// given to motion or executed by the task controller. Non-realtime.
#pragma once

#include <string>

#include "core/motion/command.hpp"
#include "core/tooltable/tool_table.hpp"

namespace cnc::task {

struct Item {
  enum class Kind : uint8_t {
    Motion,        // a motion command (segment, dwell, synchronised output, ...): queued without waiting
    MotionAtRest,  // a motion command that waits until motion is at rest (spindle, overrides...)
    ProbeCheck,    // after a probe: was there contact when it was required?
    ToolPrepare,   // T: i0 = tool number
    ToolChange,    // M6: i0 = tooldata index
    ToolNumber,    // M61: i0 = tooldata index
    ToolSetEntry,  // G10 L1/L10/L11: tool
    Flood,         // i0 = on
    Mist,          // i0 = on
    Message,       // (MSG,...): text
    WaitOrient,    // M19 Q: i0 = spindle, d0 = timeout
    WaitInput,     // M66: i0 = index, i1 = digital, i2 = wait type, d0 = timeout
    UserMCode,     // M100-M199: i0 = code, d0 = P, d1 = Q
    ProgramStop,   // M0 / M60 (pauses)
    OptionalStop,  // M1
    ProgramEnd,    // M2 / M30
    StepMark,      // end of a block in single-block mode
  };
  Kind kind = Kind::Motion;
  int line = 0;
  motion::MotionCommand motion;
  int i0 = 0, i1 = 0, i2 = 0;
  double d0 = 0, d1 = 0;
  std::string text;
  tooltable::Tool tool;
  bool probe_must_touch = false;
  // The modal state after the block that made this item (tp::StateTag);
  // Motion items carry it in motion.segment.tag as well, through the planner.
  tp::StateTag tag;
};

}  // namespace cnc::task
