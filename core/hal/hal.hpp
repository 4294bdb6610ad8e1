// The HAL of one controller: pins, parameters, signals, functions, threads
// and the components that own them. Everything here is non-realtime and
// thread-safe (one mutex); the servo thread only touches cells through the
// handles of pin.hpp and runs thread function lists, never this class.
#pragma once

#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "core/hal/objects.hpp"
#include "core/hal/pin.hpp"
#include "core/hal/thread.hpp"

namespace cnc::hal {

class Component;

// Read-only views for halcmd's show and list.
struct PinView {
  std::string name, owner, signal;
  Type type;
  PinDir dir;
  uint64_t value;
};
struct ParamView {
  std::string name, owner;
  Type type;
  ParamDir dir;
  uint64_t value;
};
struct SignalView {
  std::string name;
  Type type;
  uint64_t value;
  std::string writer;                 // OUT pin, if any
  std::vector<std::string> readers;   // IN pins
  std::vector<std::string> bidirs;    // I/O pins
};
struct FunctionView {
  std::string name, owner;
  bool uses_fp;
  int users;
  int64_t time_ns, tmax_ns;
};
struct ThreadView {
  std::string name;
  int64_t period_ns;
  bool uses_fp, running;
  int64_t time_ns, tmax_ns;
  std::vector<std::string> functions;
};

class Hal {
 public:
  Hal();
  ~Hal();
  Hal(const Hal&) = delete;
  Hal& operator=(const Hal&) = delete;

  // --- creation, used by components (throws HalError) ---
  template <class T>
  Pin<T> new_pin(Component* owner, const std::string& name, PinDir dir, T initial = T{}) {
    return Pin<T>(create_pin(owner, name, type_of<T>(), dir, encode<T>(initial)));
  }
  template <class T>
  Param<T> new_param(Component* owner, const std::string& name, ParamDir dir, T initial = T{}) {
    return Param<T>(create_param(owner, name, type_of<T>(), dir, encode<T>(initial)));
  }
  void export_function(Component* owner, const std::string& name, FunctionFn fn, void* arg, bool uses_fp = true);
  Thread& new_thread(const std::string& name, int64_t period_ns, bool uses_fp = true);
  // The overrun limit of every thread, present and future (Thread::set_overrun_limit).
  void set_overrun_limit(uint32_t cycles);

  // --- components ---
  Component& add_component(std::unique_ptr<Component> c);
  Component* find_component(const std::string& name) const;
  template <class C>
  C* find(const std::string& name) const { return dynamic_cast<C*>(find_component(name)); }
  std::vector<Component*> components() const;

  // --- graph edits (halcmd) ---
  void new_signal(const std::string& name, Type type);
  void delete_signal(const std::string& name);
  // Creates the signal (typed by the first pin) if needed, then links pins.
  void net(const std::string& signal, const std::vector<std::string>& pins);
  void link(const std::string& pin, const std::string& signal);
  void unlink(const std::string& pin);
  // linkpp: joins two pins through a signal named after the output pin.
  void link_pins(const std::string& a, const std::string& b);
  void add_function(const std::string& function, const std::string& thread, int position = -1);
  void remove_function(const std::string& function, const std::string& thread);

  // --- values (halcmd) ---
  // setp: an unconnected IN or I/O pin, or an RW parameter.
  void set_value(const std::string& pin_or_param, const std::string& text);
  std::string get_value(const std::string& pin_or_param) const;
  // Writes a pin of any direction whose owner passes `is_owner` (remote
  // components writing their own outputs).
  void set_owned_pin(const std::string& pin, const std::string& text, bool (*is_owner)(const Component*));
  void set_signal(const std::string& signal, const std::string& text);
  std::string get_signal(const std::string& signal) const;
  Type type_of_name(const std::string& pin_or_param) const;
  Type signal_type(const std::string& signal) const;

  // --- threads ---
  void start_threads();
  void stop_threads();
  bool threads_running() const;
  Thread* find_thread(const std::string& name);
  std::vector<Thread*> threads() const;

  // --- views ---
  std::vector<PinView> pins() const;
  std::vector<ParamView> params() const;
  std::vector<SignalView> signals() const;
  std::vector<FunctionView> functions() const;
  std::vector<ThreadView> thread_views() const;
  bool has_pin(const std::string& name) const;
  // The pin object, for readers outside its owner (the scope samples
  // `cell` in the servo thread); throws HalError when it does not exist.
  // Pins live as long as their component.
  const detail::PinObj* find_pin(const std::string& name) const;
  bool has_param(const std::string& name) const;

  // Destroys components (on_shutdown is the daemon's job) after threads stop.
  void clear();
  // Removes the pins, parameters and functions whose owner is not a loaded
  // component: those of a component that failed to load (its constructor
  // threw half-way, or its name was taken), which would otherwise point at
  // a destroyed object. Pins are unlinked, functions taken out of threads.
  void remove_orphans();

 private:
  detail::PinObj* create_pin(Component* owner, const std::string& name, Type type, PinDir dir, uint64_t initial);
  detail::ParamObj* create_param(Component* owner, const std::string& name, Type type, ParamDir dir,
                                 uint64_t initial);
  void check_unique(const std::string& name) const;
  detail::SignalObj* new_signal_locked(const std::string& name, Type type, bool named_after_pin = false);
  void net_impl(const std::string& signal, const std::vector<std::string>& pins, bool named_after_pin);
  void link_locked(detail::PinObj* pin, detail::SignalObj* sig);
  void unlink_locked(detail::PinObj* pin);
  detail::PinObj* pin_locked(const std::string& name) const;
  detail::SignalObj* signal_locked(const std::string& name) const;
  Function* function_locked(const std::string& name) const;
  Thread* thread_locked(const std::string& name) const;

  mutable std::mutex mutex_;
  std::map<std::string, std::unique_ptr<detail::PinObj>> pins_;
  std::map<std::string, std::unique_ptr<detail::ParamObj>> params_;
  std::map<std::string, detail::SignalObj*> signals_;
  std::deque<std::unique_ptr<detail::SignalObj>> signal_storage_;  // never freed while running
  std::map<std::string, std::unique_ptr<Function>> functions_;
  std::map<std::string, std::unique_ptr<Thread>> threads_;
  std::vector<std::unique_ptr<Component>> components_;
  uint32_t overrun_limit_ = Thread::kDefaultOverrunLimit;
};

}  // namespace cnc::hal
