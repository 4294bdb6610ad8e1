// The HAL's objects as it stores them. Components use the typed handles of
// pin.hpp instead; halcmd and the HAL itself use these.
#pragma once

#include <atomic>
#include <string>
#include <vector>

#include "core/hal/types.hpp"
#include "core/rt/cycle_info.hpp"

namespace cnc::hal {

class Component;

namespace detail {

struct SignalObj;

struct PinObj {
  std::string name;
  Type type;
  PinDir dir;
  Component* owner = nullptr;
  std::atomic<Cell*> cell{nullptr};  // own storage or the linked signal's
  Cell own;
  SignalObj* signal = nullptr;       // guarded by the HAL mutex
};

struct ParamObj {
  std::string name;
  Type type;
  ParamDir dir;
  Component* owner = nullptr;
  Cell cell;
};

struct SignalObj {
  std::string name;
  Type type;
  Cell cell;
  std::vector<PinObj*> pins;  // guarded by the HAL mutex
  bool deleted = false;       // storage stays valid: the servo thread may hold it
};

}  // namespace detail

// A realtime function: a plain pointer and an argument, no virtual call.
using FunctionFn = void (*)(void* arg, const rt::CycleInfo& cycle);

struct Function {
  std::string name;
  FunctionFn fn = nullptr;
  void* arg = nullptr;
  Component* owner = nullptr;
  bool uses_fp = true;
  int users = 0;                         // threads it is added to
  detail::ParamObj* time = nullptr;      // <name>.time: last execution, ns
  detail::ParamObj* tmax = nullptr;      // <name>.tmax: maximum, ns (writable to reset)
  // Overruns blamed on this function (it ran longest in a cycle that ended
  // after its deadline, and longer than the thread's late wake-up).
  detail::ParamObj* overruns = nullptr;  // <name>.overruns (u32)
  std::atomic<int64_t> overrun_max_ns{0};  // its longest run in such a cycle
};

}  // namespace cnc::hal
