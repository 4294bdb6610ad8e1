// Range checks of a command's numeric arguments, the same for every client
// (cnc, the screen, scripts): indexes inside their tables, flags 0 or 1,
// enumerations among their values, reals finite and of a magnitude a machine
// can mean. The controller refuses a command that fails them before any part
// of it acts, so no value wraps, no NaN or infinity reaches motion and no
// 1e308 becomes a set-point. Limits of the machine itself (velocities,
// speeds, travel) are its parameters' owners' to enforce; these are the
// bounds below which those owners can work.
#pragma once

#include <string>

#include "core/ipc/command.hpp"

namespace cnc::ipc {

// Largest magnitude accepted for a length, position or velocity argument
// (units or units/s), a spindle speed (rpm) and an override scale.
inline constexpr double kMaxLinearArgument = 1e6;
inline constexpr double kMaxSpindleRpm = 1e6;
inline constexpr double kMaxOverrideScale = 10;  // 1000 %
inline constexpr int kMaxMotionIo = 64;          // motion.digital-*/analog-* pins

// Empty when every argument `cmd` uses is in range; otherwise the reason,
// naming the argument, its value and the range expected.
std::string check_arguments(const Command& cmd);

}  // namespace cnc::ipc
