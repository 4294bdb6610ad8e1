// HAL components: C++ classes that declare pins, parameters and functions,
// created by name from a .hal file's `loadrt name args`. Components never
// block in their realtime functions and never allocate there.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/hal/hal.hpp"

namespace cnc {
class MessageQueue;
namespace ini {
class IniFile;
}
}  // namespace cnc

namespace cnc::hal {

class Component {
 public:
  Component(Hal& hal, std::string name) : hal_(hal), name_(std::move(name)) {}
  virtual ~Component() = default;
  Component(const Component&) = delete;
  Component& operator=(const Component&) = delete;

  const std::string& name() const noexcept { return name_; }
  // A simulator (sim/), not part of the product: the time its functions
  // take is counted apart from the product's in its thread's status.
  bool is_simulation() const noexcept { return simulation_; }

  // After every HAL file has run and before the threads start.
  virtual void on_ready() {}
  // The controller is stopping and the threads still run: bring outputs to
  // a safe state (disable drives, stop the spindle). Called once.
  virtual void on_shutdown() {}

 protected:
  Hal& hal() noexcept { return hal_; }
  // For simulators, in their constructor (before their functions are added
  // to a thread).
  void mark_as_simulation() noexcept { simulation_ = true; }
  template <class T>
  Pin<T> make_pin(const std::string& name, PinDir dir, T initial = T{}) {
    return hal_.new_pin<T>(this, name, dir, initial);
  }
  template <class T>
  Param<T> make_param(const std::string& name, ParamDir dir, T initial = T{}) {
    return hal_.new_param<T>(this, name, dir, initial);
  }
  // Exports a member function `void C::f(const rt::CycleInfo&) noexcept`.
  template <auto Method, class C>
  void export_method(const std::string& function_name, C* self, bool uses_fp = true) {
    hal_.export_function(
        this, function_name,
        [](void* arg, const rt::CycleInfo& info) { (static_cast<C*>(arg)->*Method)(info); }, self, uses_fp);
  }

 private:
  Hal& hal_;
  std::string name_;
  bool simulation_ = false;
};

// The arguments of `loadrt name key=value ...`.
class LoadArgs {
 public:
  LoadArgs(std::string component, std::vector<std::pair<std::string, std::string>> values)
      : component_(std::move(component)), values_(std::move(values)) {}

  const std::string& component() const noexcept { return component_; }
  std::optional<std::string> get(const std::string& key) const;
  std::string get_string(const std::string& key, const std::string& def) const;
  int64_t get_int(const std::string& key, int64_t def, int64_t min, int64_t max) const;
  double get_double(const std::string& key, double def) const;
  // Instance names from `names=a,b` or `<count_key>=N` (prefix.0 ...
  // prefix.N-1); count_key is LinuxCNC's for the component: `count` for
  // most, `num_chan` for pid, siggen and encoder.
  std::vector<std::string> instance_names(const std::string& prefix, int default_count = 1, int max_count = 64,
                                          const std::string& count_key = "count") const;
  // Throws naming any key not in `known`.
  void allow_only(const std::vector<std::string>& known) const;
  const std::vector<std::pair<std::string, std::string>>& values() const noexcept { return values_; }

 private:
  std::string component_;
  std::vector<std::pair<std::string, std::string>> values_;
};

// What a component factory may use besides its arguments.
struct ComponentContext {
  Hal& hal;
  const ini::IniFile* ini = nullptr;  // null when no INI was given
  MessageQueue* messages = nullptr;   // the error channel; null in some tests
};

using ComponentFactory = std::function<std::unique_ptr<Component>(ComponentContext&, const LoadArgs&)>;

class ComponentRegistry {
 public:
  struct Entry {
    std::string name;
    std::string help;  // one line: what it is and its arguments
    ComponentFactory factory;
  };
  void add(const std::string& name, const std::string& help, ComponentFactory factory);
  const Entry* find(const std::string& name) const;
  std::vector<const Entry*> entries() const;

 private:
  std::map<std::string, Entry> entries_;
};

// Components every controller has: threads, and the small logic and math
// blocks HAL files use (and2, or2, not, mux2, sum2, scale, ...).
// Includes register_panel_components.
void register_core_components(ComponentRegistry& registry);
// The panel building blocks (panel_components.cpp, docs/hal.md): mux4,
// select8, debounce, limit3, pid, toggle, edge, timedelay, conv_*, encoder.
void register_panel_components(ComponentRegistry& registry);

}  // namespace cnc::hal
