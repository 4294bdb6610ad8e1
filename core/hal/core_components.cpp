// The small components every HAL setup needs. Each follows LinuxCNC's
// interface for the component of the same name, so HAL files carry over:
// one function per instance, named after the instance (addf and2.0 ...).
#include <cmath>

#include "core/hal/component.hpp"
#include "core/hal/instances.hpp"
#include "core/hal/latch.hpp"
#include "core/util/strings.hpp"

namespace cnc::hal {
namespace {

// `loadrt threads name1=servo-thread period1=1000000 [fp1=1] [name2=...]`
class ThreadsComponent : public Component {
 public:
  ThreadsComponent(ComponentContext& ctx, const LoadArgs& args) : Component(ctx.hal, "threads") {
    for (int i = 1; i <= 3; ++i) {
      const auto name = args.get("name" + std::to_string(i));
      const auto period = args.get_int("period" + std::to_string(i), 0, 0, 1'000'000'000);
      if (!name && period == 0) continue;
      if (!name) throw HalError("threads: period" + std::to_string(i) + " given without name" + std::to_string(i));
      if (period == 0) throw HalError("threads: name" + std::to_string(i) + "=" + *name + " needs period" + std::to_string(i));
      const bool fp = args.get_int("fp" + std::to_string(i), 1, 0, 1) != 0;
      ctx.hal.new_thread(*name, period, fp);
    }
    std::vector<std::string> known;
    for (int i = 1; i <= 3; ++i) {
      for (const char* k : {"name", "period", "fp"}) known.push_back(k + std::to_string(i));
    }
    args.allow_only(known);
  }
};

struct And2 {
  BitPin in0, in1, out;
  template <class C> void make(C& c, const std::string& n) {
    in0 = c.template pin<bool>(n + ".in0", PinDir::In);
    in1 = c.template pin<bool>(n + ".in1", PinDir::In);
    out = c.template pin<bool>(n + ".out", PinDir::Out);
  }
  void update(const rt::CycleInfo&) noexcept { out.set(in0.get() && in1.get()); }
};

struct Or2 {
  BitPin in0, in1, out;
  template <class C> void make(C& c, const std::string& n) {
    in0 = c.template pin<bool>(n + ".in0", PinDir::In);
    in1 = c.template pin<bool>(n + ".in1", PinDir::In);
    out = c.template pin<bool>(n + ".out", PinDir::Out);
  }
  void update(const rt::CycleInfo&) noexcept { out.set(in0.get() || in1.get()); }
};

struct Xor2 {
  BitPin in0, in1, out;
  template <class C> void make(C& c, const std::string& n) {
    in0 = c.template pin<bool>(n + ".in0", PinDir::In);
    in1 = c.template pin<bool>(n + ".in1", PinDir::In);
    out = c.template pin<bool>(n + ".out", PinDir::Out);
  }
  void update(const rt::CycleInfo&) noexcept { out.set(in0.get() != in1.get()); }
};

struct Not {
  BitPin in, out;
  template <class C> void make(C& c, const std::string& n) {
    in = c.template pin<bool>(n + ".in", PinDir::In);
    // FALSE until the function first runs, as LinuxCNC's.
    out = c.template pin<bool>(n + ".out", PinDir::Out);
  }
  void update(const rt::CycleInfo&) noexcept { out.set(!in.get()); }
};

struct Mux2 {
  BitPin sel;
  FloatPin in0, in1, out;
  template <class C> void make(C& c, const std::string& n) {
    sel = c.template pin<bool>(n + ".sel", PinDir::In);
    in0 = c.template pin<double>(n + ".in0", PinDir::In);
    in1 = c.template pin<double>(n + ".in1", PinDir::In);
    out = c.template pin<double>(n + ".out", PinDir::Out);
  }
  void update(const rt::CycleInfo&) noexcept { out.set(sel.get() ? in1.get() : in0.get()); }
};

// sum2: gains and offset are parameters, as LinuxCNC's.
struct Sum2 {
  FloatPin in0, in1, out;
  Param<double> gain0, gain1, offset;
  template <class C> void make(C& c, const std::string& n) {
    in0 = c.template pin<double>(n + ".in0", PinDir::In);
    in1 = c.template pin<double>(n + ".in1", PinDir::In);
    gain0 = c.template param<double>(n + ".gain0", ParamDir::RW, 1.0);
    gain1 = c.template param<double>(n + ".gain1", ParamDir::RW, 1.0);
    offset = c.template param<double>(n + ".offset", ParamDir::RW, 0.0);
    out = c.template pin<double>(n + ".out", PinDir::Out);
  }
  void update(const rt::CycleInfo&) noexcept {
    out.set(in0.get() * gain0.get() + in1.get() * gain1.get() + offset.get());
  }
};

struct Scale {
  FloatPin in, gain, offset, out;
  template <class C> void make(C& c, const std::string& n) {
    in = c.template pin<double>(n + ".in", PinDir::In);
    gain = c.template pin<double>(n + ".gain", PinDir::In);  // 0, as LinuxCNC's: set it
    offset = c.template pin<double>(n + ".offset", PinDir::In);
    out = c.template pin<double>(n + ".out", PinDir::Out);
  }
  void update(const rt::CycleInfo&) noexcept { out.set(in.get() * gain.get() + offset.get()); }
};

// First-order low-pass: out += (in - out) * gain each cycle.
// gain is a parameter, 0 (out holds) until set, as LinuxCNC's.
struct Lowpass {
  FloatPin in, out;
  Param<double> gain;
  BitPin load;
  template <class C> void make(C& c, const std::string& n) {
    in = c.template pin<double>(n + ".in", PinDir::In);
    gain = c.template param<double>(n + ".gain", ParamDir::RW, 0.0);
    load = c.template pin<bool>(n + ".load", PinDir::In);
    out = c.template pin<double>(n + ".out", PinDir::Out);
  }
  void update(const rt::CycleInfo&) noexcept {
    if (load.get()) out.set(in.get());
    else out.set(out.get() + (in.get() - out.get()) * gain.get());
  }
};

// Derivative with respect to time, using the measured period.
struct Ddt {
  FloatPin in, out;
  double last = 0;
  bool primed = false;
  template <class C> void make(C& c, const std::string& n) {
    in = c.template pin<double>(n + ".in", PinDir::In);
    out = c.template pin<double>(n + ".out", PinDir::Out);
  }
  void update(const rt::CycleInfo& info) noexcept {
    const double x = in.get();
    const double dt = static_cast<double>(info.actual_period_ns) * 1e-9;
    out.set(primed && dt > 0 ? (x - last) / dt : 0.0);
    last = x;
    primed = true;
  }
};

// LinuxCNC's estop_latch: ok-out stays false after a fault until a rising
// edge on reset while ok-in is true and fault-in is false.
struct EstopLatch {
  BitPin ok_in, fault_in, reset, ok_out, fault_out, watchdog;
  bool old_reset = false;
  template <class C> void make(C& c, const std::string& n) {
    ok_in = c.template pin<bool>(n + ".ok-in", PinDir::In, true);
    fault_in = c.template pin<bool>(n + ".fault-in", PinDir::In);
    reset = c.template pin<bool>(n + ".reset", PinDir::In);
    ok_out = c.template pin<bool>(n + ".ok-out", PinDir::Out);
    fault_out = c.template pin<bool>(n + ".fault-out", PinDir::Out, true);
    watchdog = c.template pin<bool>(n + ".watchdog", PinDir::Out);
  }
  void update(const rt::CycleInfo&) noexcept {
    const bool r = reset.get();
    if (!ok_in.get() || fault_in.get()) {
      ok_out.set(false);
    } else if (r && !old_reset) {
      ok_out.set(true);
    }
    old_reset = r;
    fault_out.set(!ok_out.get());
    watchdog.set(ok_out.get() && !watchdog.get());
  }
};

// Signal generator: sine, cosine, triangle, square and sawtooth outputs.
struct Siggen {
  FloatPin frequency, amplitude, offset, sine, cosine, triangle, square, sawtooth;
  BitPin clock, reset;
  double phase = 0;
  template <class C> void make(C& c, const std::string& n) {
    frequency = c.template pin<double>(n + ".frequency", PinDir::In, 1.0);
    amplitude = c.template pin<double>(n + ".amplitude", PinDir::In, 1.0);
    offset = c.template pin<double>(n + ".offset", PinDir::In);
    sine = c.template pin<double>(n + ".sine", PinDir::Out);
    cosine = c.template pin<double>(n + ".cosine", PinDir::Out);
    triangle = c.template pin<double>(n + ".triangle", PinDir::Out);
    square = c.template pin<double>(n + ".square", PinDir::Out);
    sawtooth = c.template pin<double>(n + ".sawtooth", PinDir::Out);
    clock = c.template pin<bool>(n + ".clock", PinDir::Out);
    reset = c.template pin<bool>(n + ".reset", PinDir::In);
  }
  void update(const rt::CycleInfo& info) noexcept {
    if (reset.get()) {
      // Held at the start of a period; the states LinuxCNC's man page names.
      phase = 0;
      const double a = amplitude.get();
      sine.set(0);
      sawtooth.set(0);
      square.set(-a);
      cosine.set(-a);
      triangle.set(-a);
      return;
    }
    phase += frequency.get() * static_cast<double>(info.actual_period_ns) * 1e-9;
    phase -= std::floor(phase);
    const double a = amplitude.get(), o = offset.get();
    sine.set(o + a * std::sin(2 * M_PI * phase));
    cosine.set(o + a * std::cos(2 * M_PI * phase));
    triangle.set(o + a * (phase < 0.5 ? 4 * phase - 1 : 3 - 4 * phase));
    square.set(o + (phase < 0.5 ? a : -a));
    sawtooth.set(o + a * (2 * phase - 1));
    clock.set(phase < 0.5);
  }
};


}  // namespace

void register_core_components(ComponentRegistry& r) {
  r.add("threads", "threads name1=<thread> period1=<ns> [fp1=0|1] (up to 3): create periodic threads",
        [](ComponentContext& ctx, const LoadArgs& args) -> std::unique_ptr<Component> {
          return std::make_unique<ThreadsComponent>(ctx, args);
        });
  add_instances<And2>(r, "and2", "and2", "and2 [count=N|names=a,b]: out = in0 AND in1");
  add_instances<Or2>(r, "or2", "or2", "or2 [count=N|names=a,b]: out = in0 OR in1");
  add_instances<Xor2>(r, "xor2", "xor2", "xor2 [count=N|names=a,b]: out = in0 XOR in1");
  add_instances<Not>(r, "not", "not", "not [count=N|names=a,b]: out = NOT in");
  add_instances<Mux2>(r, "mux2", "mux2", "mux2 [count=N|names=a,b]: out = sel ? in1 : in0");
  add_instances<Sum2>(r, "sum2", "sum2", "sum2 [count=N|names=a,b]: out = in0*gain0 + in1*gain1 + offset");
  add_instances<Scale>(r, "scale", "scale", "scale [count=N|names=a,b]: out = in*gain + offset");
  add_instances<Lowpass>(r, "lowpass", "lowpass", "lowpass [count=N|names=a,b]: first-order filter, out += (in-out)*gain");
  add_instances<Ddt>(r, "ddt", "ddt", "ddt [count=N|names=a,b]: out = d(in)/dt over the measured period");
  add_instances<EstopLatch>(r, "estop_latch", "estop-latch",
                        "estop_latch [count=N|names=a,b]: latch a fault until reset (LinuxCNC's estop_latch)");
  add_instances<Siggen>(r, "siggen", "siggen", "siggen [num_chan=N|names=a,b]: sine, cosine, triangle, square, sawtooth",
                     "num_chan", ".update");
  register_latch_component(r);
  register_panel_components(r);
}

}  // namespace cnc::hal
