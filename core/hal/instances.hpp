// A component made of instances of one shape (and2.0, pid.1, ...): each
// instance is a struct with `make(component, name)` creating its pins and
// parameters and `update(info)`, the realtime function exported as
// `<instance><suffix>` (LinuxCNC: and2.0, pid.0.do-pid-calcs). Instances
// come from `count=`/`names=` (or the component's own count key, such as
// pid's num_chan=).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/hal/component.hpp"

namespace cnc::hal {

template <class Instance>
class Instances : public Component {
 public:
  Instances(ComponentContext& ctx, const LoadArgs& args, const std::string& prefix, const std::string& count_key,
            const std::string& suffix)
      : Component(ctx.hal, args.component()) {
    args.allow_only({count_key, "names"});
    for (const auto& n : args.instance_names(prefix, 1, 64, count_key)) {
      instances_.push_back(std::make_unique<Instance>());
      Instance& inst = *instances_.back();
      inst.make(*this, n);
      hal().export_function(
          this, n + suffix, [](void* arg, const rt::CycleInfo& info) { static_cast<Instance*>(arg)->update(info); },
          &inst);
    }
  }
  template <class T>
  Pin<T> pin(const std::string& name, PinDir dir, T initial = T{}) { return make_pin<T>(name, dir, initial); }
  template <class T>
  Param<T> param(const std::string& name, ParamDir dir, T initial = T{}) { return make_param<T>(name, dir, initial); }

 private:
  std::vector<std::unique_ptr<Instance>> instances_;
};

// Registers component `comp` whose instances are named `<prefix>.N` (or as
// given by names=).
template <class Instance>
void add_instances(ComponentRegistry& r, const std::string& comp, const std::string& prefix, const std::string& help,
                   const std::string& count_key = "count", const std::string& suffix = "") {
  r.add(comp, help, [prefix, count_key, suffix](ComponentContext& ctx, const LoadArgs& args) -> std::unique_ptr<Component> {
    return std::make_unique<Instances<Instance>>(ctx, args, prefix, count_key, suffix);
  });
}

}  // namespace cnc::hal
