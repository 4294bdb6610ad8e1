// The HAL building blocks machine builders wire panels with: mux4, select8,
// debounce, limit3, pid, toggle, edge, timedelay, the conv_* family and the
// software encoder for handwheels. Each keeps LinuxCNC's component, pin,
// parameter and function names (docs/hal.md lists them), so panel HAL files
// carry over. Realtime functions only read and write cells and plain
// members: no allocation, no lock, no throw.
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/hal/component.hpp"
#include "core/hal/instances.hpp"
#include "core/hal/scope.hpp"
#include "core/util/strings.hpp"

namespace cnc::hal {
namespace {

// Seconds of the current cycle: the nominal period (deterministic for
// pid/limit3), the measured one when a caller runs cycles without a period.
double cycle_seconds(const rt::CycleInfo& info) noexcept {
  const int64_t ns = info.period_ns > 0 ? info.period_ns : info.actual_period_ns;
  return static_cast<double>(ns) * 1e-9;
}


// mux4: out = in[sel1*2 + sel0].
struct Mux4 {
  BitPin sel0, sel1;
  FloatPin in[4], out;
  template <class C> void make(C& c, const std::string& n) {
    sel0 = c.template pin<bool>(n + ".sel0", PinDir::In);
    sel1 = c.template pin<bool>(n + ".sel1", PinDir::In);
    for (int i = 0; i < 4; ++i) in[i] = c.template pin<double>(n + ".in" + std::to_string(i), PinDir::In);
    out = c.template pin<double>(n + ".out", PinDir::Out);
  }
  void update(const rt::CycleInfo&) noexcept { out.set(in[(sel1.get() ? 2 : 0) + (sel0.get() ? 1 : 0)].get()); }
};

// select8: outN is TRUE when sel == N and enable is TRUE.
struct Select8 {
  S32Pin sel;
  BitPin enable, out[8];
  template <class C> void make(C& c, const std::string& n) {
    sel = c.template pin<int32_t>(n + ".sel", PinDir::In);
    enable = c.template pin<bool>(n + ".enable", PinDir::In, true);
    for (int i = 0; i < 8; ++i) out[i] = c.template pin<bool>(n + ".out" + std::to_string(i), PinDir::Out);
  }
  void update(const rt::CycleInfo&) noexcept {
    const int32_t s = sel.get();
    const bool en = enable.get();
    for (int i = 0; i < 8; ++i) out[i].set(en && s == i);
  }
};

// toggle: each press (a rising edge of in, held for `debounce` cycles)
// inverts out. out is I/O so a screen or another toggle can set it too.
struct Toggle {
  BitPin in, out;
  Param<uint32_t> debounce;
  uint32_t count = 0;
  bool pressed = false;
  template <class C> void make(C& c, const std::string& n) {
    in = c.template pin<bool>(n + ".in", PinDir::In);
    out = c.template pin<bool>(n + ".out", PinDir::IO);
    debounce = c.template param<uint32_t>(n + ".debounce", ParamDir::RW, 2u);
  }
  void update(const rt::CycleInfo&) noexcept {
    const uint32_t limit = debounce.get();
    if (in.get()) {
      if (count < limit) ++count;
    } else if (count > 0) {
      --count;
    }
    if (!pressed && count >= limit && in.get()) {
      pressed = true;
      out.set(!out.get());
    } else if (pressed && count == 0) {
      pressed = false;
    }
  }
};

// edge: a pulse of out-width-ns (at least one cycle) on the chosen edge of
// in: rising when in-edge is TRUE, falling when FALSE, either when both.
struct Edge {
  BitPin in, out, out_invert;
  Param<bool> both, in_edge, last_in;
  Param<int32_t> out_width_ns, time_left_ns;
  template <class C> void make(C& c, const std::string& n) {
    in = c.template pin<bool>(n + ".in", PinDir::In);
    out = c.template pin<bool>(n + ".out", PinDir::Out);
    out_invert = c.template pin<bool>(n + ".out-invert", PinDir::Out);  // FALSE until it first runs
    both = c.template param<bool>(n + ".both", ParamDir::RW, false);
    in_edge = c.template param<bool>(n + ".in-edge", ParamDir::RW, true);
    out_width_ns = c.template param<int32_t>(n + ".out-width-ns", ParamDir::RW, 0);
    time_left_ns = c.template param<int32_t>(n + ".time-left-ns", ParamDir::RO, 0);
    last_in = c.template param<bool>(n + ".last-in", ParamDir::RO, false);
  }
  void update(const rt::CycleInfo& info) noexcept {
    const bool now = in.get();
    const bool before = last_in.get();
    // As LinuxCNC's: last-in starts FALSE, so an input TRUE at start is a
    // rising edge.
    const bool fire = now != before && (both.get() || now == in_edge.get());
    last_in.set(now);
    int64_t left = time_left_ns.get();
    const int64_t period = info.period_ns > 0 ? info.period_ns : info.actual_period_ns;
    if (fire) {
      out.set(true);
      left = out_width_ns.get();
    } else if (left > 0) {
      left -= period;
      out.set(left > 0);
    } else {
      out.set(false);
    }
    if (left < 0) left = 0;
    time_left_ns.set(static_cast<int32_t>(left));
    out_invert.set(!out.get());
  }
};

// timedelay: out follows in once in has been steady for on-delay (to TRUE)
// or off-delay (to FALSE) seconds; elapsed is the time in the current wait.
struct Timedelay {
  BitPin in, out;
  FloatPin on_delay, off_delay, elapsed;
  double timer = 0;
  template <class C> void make(C& c, const std::string& n) {
    in = c.template pin<bool>(n + ".in", PinDir::In);
    out = c.template pin<bool>(n + ".out", PinDir::Out);
    on_delay = c.template pin<double>(n + ".on-delay", PinDir::In, 0.5);
    off_delay = c.template pin<double>(n + ".off-delay", PinDir::In, 0.5);
    elapsed = c.template pin<double>(n + ".elapsed", PinDir::Out);
  }
  void update(const rt::CycleInfo& info) noexcept {
    const bool want = in.get();
    if (want == out.get()) {
      timer = 0;
    } else {
      timer += cycle_seconds(info);
      if (timer >= (want ? on_delay.get() : off_delay.get())) {
        out.set(want);
        timer = 0;
      }
    }
    elapsed.set(timer);
  }
};

// limit3: out follows in, clamped to [min, max], with |velocity| <= maxv and
// |acceleration| <= maxa, braking in time to stop on the target without
// overshoot (the discrete stopping distance of one-cycle steps is used).
// load jumps out to the clamped in. maxv/maxa <= 0 means no such limit.
// enable FALSE steers out back to 0 the same way.
struct Limit3 {
  FloatPin in, min_, max_, maxv, maxa, out;
  BitPin load, enable;
  double vel = 0;
  template <class C> void make(C& c, const std::string& n) {
    in = c.template pin<double>(n + ".in", PinDir::In);
    min_ = c.template pin<double>(n + ".min", PinDir::In, -1e20);
    max_ = c.template pin<double>(n + ".max", PinDir::In, 1e20);
    maxv = c.template pin<double>(n + ".maxv", PinDir::In, 1e20);
    maxa = c.template pin<double>(n + ".maxa", PinDir::In, 1e20);
    load = c.template pin<bool>(n + ".load", PinDir::In);
    enable = c.template pin<bool>(n + ".enable", PinDir::In, true);
    out = c.template pin<double>(n + ".out", PinDir::Out);
  }
  void update(const rt::CycleInfo& info) noexcept {
    const double dt = cycle_seconds(info);
    // enable FALSE: out returns to 0, within the same limits.
    const double target = std::clamp(enable.get() ? in.get() : 0.0, std::min(min_.get(), max_.get()), max_.get());
    const double pos = out.get();
    if (load.get() || dt <= 0) {
      out.set(target);
      vel = 0;
      return;
    }
    const double vmax = maxv.get() > 0 ? maxv.get() : 1e300;
    const double amax = maxa.get() > 0 ? maxa.get() : 1e300;
    const double dv = amax * dt;  // the most velocity may change in one cycle
    const double dist = target - pos;
    // Fastest speed from which braking by dv per cycle still stops within
    // |dist|: moving v this cycle and v-dv, v-2dv, ... after it covers
    // dt*v*(v/dv + 1)/2.
    const double d = std::fabs(dist);
    // The root of v^2 + dv*v - 2*dv*d/dt = 0 in its cancellation-free form.
    const double v_stop = amax >= 1e150 ? d / dt : 4.0 * dv * d / dt / (dv + std::sqrt(dv * dv + 8.0 * dv * d / dt));
    double want = std::copysign(std::min({vmax, v_stop, d / dt}), dist);
    want = std::clamp(want, vel - dv, vel + dv);
    want = std::clamp(want, -vmax, vmax);
    const double next = pos + want * dt;
    vel = want;
    out.set(next);
  }
};

// pid: LinuxCNC's pid with the essential pin set (docs/hal.md). Error
// derivatives use the nominal period; the integrator stops while the output
// saturates unless the error brings it back (anti-windup).
struct Pid {
  FloatPin pgain, igain, dgain, bias, ff0, ff1, ff2, deadband, maxerror, maxerror_i, maxerror_d, maxcmd_d,
      maxcmd_dd, maxoutput;
  FloatPin command, feedback, error, output, error_i, error_d, command_d, command_dd, saturated_s;
  BitPin enable, index_enable, saturated;
  S32Pin saturated_count;
  double prev_error = 0, prev_cmd = 0, prev_cmd_d = 0;
  bool prev_index_enable = false, primed = false;
  template <class C> void make(C& c, const std::string& n) {
    auto in = [&](const char* s, double init = 0.0) { return c.template pin<double>(n + "." + s, PinDir::In, init); };
    auto outp = [&](const char* s) { return c.template pin<double>(n + "." + s, PinDir::Out); };
    pgain = in("Pgain", 1.0);
    igain = in("Igain");
    dgain = in("Dgain");
    bias = in("bias");
    ff0 = in("FF0");
    ff1 = in("FF1");
    ff2 = in("FF2");
    deadband = in("deadband");
    maxerror = in("maxerror");
    maxerror_i = in("maxerrorI");
    maxerror_d = in("maxerrorD");
    maxcmd_d = in("maxcmdD");
    maxcmd_dd = in("maxcmdDD");
    maxoutput = in("maxoutput");
    command = in("command");
    feedback = in("feedback");
    error = outp("error");
    output = outp("output");
    error_i = outp("errorI");
    error_d = outp("errorD");
    command_d = outp("commandD");
    command_dd = outp("commandDD");
    saturated_s = outp("saturated-s");
    enable = c.template pin<bool>(n + ".enable", PinDir::In);
    index_enable = c.template pin<bool>(n + ".index-enable", PinDir::In);
    saturated = c.template pin<bool>(n + ".saturated", PinDir::Out);
    saturated_count = c.template pin<int32_t>(n + ".saturated-count", PinDir::Out);
  }
  static double limit(double v, double lim) noexcept { return lim > 0 ? std::clamp(v, -lim, lim) : v; }
  void update(const rt::CycleInfo& info) noexcept {
    const double dt = cycle_seconds(info);
    const double rdt = dt > 0 ? 1.0 / dt : 0.0;
    const double cmd = command.get();
    // The encoder's index reset moves command and feedback together: no
    // velocity spike in the feed-forward from the jump.
    const bool ie = index_enable.get();
    if ((prev_index_enable && !ie) || !primed) {
      prev_cmd = cmd;
      prev_cmd_d = 0;
    }
    prev_index_enable = ie;
    primed = true;
    double e = cmd - feedback.get();
    error.set(e);
    e = limit(e, maxerror.get());
    const double db = deadband.get();
    if (e > db) e -= db;
    else if (e < -db) e += db;
    else e = 0;
    const bool en = enable.get();
    double ei = error_i.get();
    if (en) {
      if (!saturated.get() || (ei > 0 && e < 0) || (ei < 0 && e > 0)) ei = limit(ei + e * dt, maxerror_i.get());
    } else {
      ei = 0;
    }
    error_i.set(ei);
    const double ed = en ? limit((e - prev_error) * rdt, maxerror_d.get()) : 0.0;
    error_d.set(ed);
    prev_error = e;
    const double cd = limit((cmd - prev_cmd) * rdt, maxcmd_d.get());
    const double cdd = limit((cd - prev_cmd_d) * rdt, maxcmd_dd.get());
    command_d.set(cd);
    command_dd.set(cdd);
    prev_cmd = cmd;
    prev_cmd_d = cd;
    if (!en) {
      output.set(0);
      saturated.set(false);
      saturated_s.set(0);
      saturated_count.set(0);
      return;
    }
    double o = bias.get() + pgain.get() * e + igain.get() * ei + dgain.get() * ed + ff0.get() * cmd +
               ff1.get() * cd + ff2.get() * cdd;
    const double mo = maxoutput.get();
    const bool sat = mo > 0 && std::fabs(o) > mo;
    o = limit(o, mo);
    output.set(o);
    saturated.set(sat);
    if (sat) {
      saturated_s.set(saturated_s.get() + dt);
      const int32_t n = saturated_count.get();
      if (n < std::numeric_limits<int32_t>::max()) saturated_count.set(n + 1);
    } else {
      saturated_s.set(0);
      saturated_count.set(0);
    }
  }
};

// debounce cfg=4,2: group G has a `delay` parameter (cycles, default 5) and
// filters G.N with in/out. out turns TRUE after in was TRUE for `delay`
// cycles net (a counter counting up while TRUE, down while FALSE) and FALSE
// once the counter is back at zero: LinuxCNC's debounce.
class Debounce : public Component {
 public:
  Debounce(ComponentContext& ctx, const LoadArgs& args) : Component(ctx.hal, "debounce") {
    args.allow_only({"cfg"});
    const auto cfg = args.get("cfg");
    if (!cfg) throw HalError("debounce: needs cfg=N[,N...] (filters per group)");
    const auto sizes = split(*cfg, ',', true);
    if (sizes.empty() || sizes.size() > 8) throw HalError("debounce: cfg=" + *cfg + ": 1 to 8 groups");
    for (std::size_t g = 0; g < sizes.size(); ++g) {
      const auto n = parse_int(sizes[g]);
      if (!n || *n < 1 || *n > 64) throw HalError("debounce: cfg=" + *cfg + ": group " + std::to_string(g) + " needs 1 to 64 filters");
      groups_.push_back(std::make_unique<Group>());
      Group& grp = *groups_.back();
      const std::string gname = "debounce." + std::to_string(g);
      grp.delay = make_param<int32_t>(gname + ".delay", ParamDir::RW, 5);
      grp.filters.resize(static_cast<std::size_t>(*n));
      for (int64_t i = 0; i < *n; ++i) {
        auto& f = grp.filters[static_cast<std::size_t>(i)];
        f.in = make_pin<bool>(gname + "." + std::to_string(i) + ".in", PinDir::In);
        f.out = make_pin<bool>(gname + "." + std::to_string(i) + ".out", PinDir::Out);
      }
      hal().export_function(
          this, gname, [](void* arg, const rt::CycleInfo&) { static_cast<Group*>(arg)->update(); }, &grp, false);
    }
  }

 private:
  struct Filter {
    BitPin in, out;
    int32_t state = 0;
  };
  struct Group {
    Param<int32_t> delay;
    std::vector<Filter> filters;
    void update() noexcept {
      const int32_t d = std::max<int32_t>(delay.get(), 0);
      for (auto& f : filters) {
        if (f.state > d) f.state = d;
        if (f.in.get()) {
          if (f.state < d) ++f.state;
          if (f.state >= d) f.out.set(true);
        } else {
          if (f.state > 0) --f.state;
          if (f.state <= 0) f.out.set(false);
        }
      }
    }
  };
  std::vector<std::unique_ptr<Group>> groups_;
};

// conv_<in>_<out>: type conversion. Where the output type cannot hold every
// input, `out-of-range` tells, and the `clamp` parameter (default FALSE, as LinuxCNC's)
// chooses between the nearest value of the output type and wrapping around
// (two's complement, as LinuxCNC's C cast does on its platforms).
template <class In, class Out>
struct Conv {
  static constexpr bool kCanOverflow =
      std::is_same_v<In, double> ||
      (!std::is_same_v<In, bool> && !std::is_same_v<Out, double> && (std::is_same_v<Out, bool> || std::is_signed_v<In> != std::is_signed_v<Out>));
  Pin<In> in;
  Pin<Out> out;
  BitPin out_of_range;
  Param<bool> clamp;
  template <class C> void make(C& c, const std::string& n) {
    in = c.template pin<In>(n + ".in", PinDir::In);
    out = c.template pin<Out>(n + ".out", PinDir::Out);
    if constexpr (kCanOverflow) {
      out_of_range = c.template pin<bool>(n + ".out-of-range", PinDir::Out);
      clamp = c.template param<bool>(n + ".clamp", ParamDir::RW, false);
    }
  }
  static double lo() noexcept { return std::is_same_v<Out, bool> ? 0.0 : static_cast<double>(std::numeric_limits<Out>::min()); }
  static double hi() noexcept { return std::is_same_v<Out, bool> ? 1.0 : static_cast<double>(std::numeric_limits<Out>::max()); }
  void update(const rt::CycleInfo&) noexcept {
    const In v = in.get();
    if constexpr (std::is_same_v<In, double>) {
      // Truncation toward zero, as a C cast.
      const double t = std::isnan(v) ? 0.0 : std::trunc(v);
      const bool bad = std::isnan(v) || t < lo() || t > hi();
      out_of_range.set(bad);
      if constexpr (std::is_same_v<Out, bool>) {
        out.set(t != 0);
      } else if (!bad || clamp.get()) {
        out.set(static_cast<Out>(std::clamp(t, lo(), hi())));
      } else {
        // Wrap: modulo 2^32 of the integer part.
        const double m = std::fmod(t, 4294967296.0);
        const auto u = static_cast<uint32_t>(static_cast<int64_t>(m < 0 ? m + 4294967296.0 : m));
        out.set(static_cast<Out>(u));
      }
    } else if constexpr (std::is_same_v<Out, double>) {
      out.set(static_cast<double>(v));
    } else if constexpr (std::is_same_v<In, bool>) {
      out.set(static_cast<Out>(v ? 1 : 0));
    } else if constexpr (std::is_same_v<Out, bool>) {
      const bool bad = v != 0 && v != 1;
      out_of_range.set(bad);
      if (clamp.get()) out.set(v > 0);
      else out.set(v != 0);
    } else {
      // s32 <-> u32
      const auto wide = static_cast<int64_t>(v);
      const bool bad = wide < static_cast<int64_t>(std::numeric_limits<Out>::min()) ||
                       wide > static_cast<int64_t>(std::numeric_limits<Out>::max());
      out_of_range.set(bad);
      if (bad && clamp.get()) out.set(wide < 0 ? std::numeric_limits<Out>::min() : std::numeric_limits<Out>::max());
      else out.set(static_cast<Out>(v));
    }
  }
};

// encoder: LinuxCNC's software encoder for handwheels (MPG) and slow
// spindles. `update-counters` decodes quadrature (or phase-A pulses in
// counter-mode) from inputs sampled each cycle it runs, or takes the change
// of a 32-bit counter on counts-in when use-counts-in is TRUE (a drive's or
// remote-I/O counter, e.g. through conv_u32_s32). `capture-position` turns
// counts into position and velocity. Both functions serve every channel;
// both may run in the servo thread (a base thread is not needed for a hand
// wheel: 1 kHz sampling counts up to 1000 edges per second reliably).
class Encoder : public Component {
 public:
  Encoder(ComponentContext& ctx, const LoadArgs& args) : Component(ctx.hal, "encoder") {
    args.allow_only({"num_chan", "names"});
    std::vector<std::string> names;
    if (const auto n = args.get("names")) {
      if (args.get("num_chan")) throw HalError("encoder: give num_chan= or names=, not both");
      names = args.instance_names("encoder");
    } else {
      const auto count = args.get_int("num_chan", 3, 1, 16);
      for (int64_t i = 0; i < count; ++i) names.push_back("encoder." + std::to_string(i));
    }
    channels_.resize(names.size());
    for (std::size_t i = 0; i < names.size(); ++i) {
      Channel& ch = channels_[i];
      const std::string& n = names[i];
      ch.phase_a = make_pin<bool>(n + ".phase-A", PinDir::In);
      ch.phase_b = make_pin<bool>(n + ".phase-B", PinDir::In);
      ch.phase_z = make_pin<bool>(n + ".phase-Z", PinDir::In);
      ch.index_enable = make_pin<bool>(n + ".index-enable", PinDir::IO);
      ch.reset = make_pin<bool>(n + ".reset", PinDir::In);
      ch.counter_mode = make_pin<bool>(n + ".counter-mode", PinDir::IO);
      ch.x4_mode = make_pin<bool>(n + ".x4-mode", PinDir::IO, true);
      ch.use_counts_in = make_pin<bool>(n + ".use-counts-in", PinDir::In);
      ch.counts_in = make_pin<int32_t>(n + ".counts-in", PinDir::In);
      ch.rawcounts = make_pin<int32_t>(n + ".rawcounts", PinDir::Out);
      ch.count = make_pin<int32_t>(n + ".counts", PinDir::Out);
      ch.position = make_pin<double>(n + ".position", PinDir::Out);
      ch.velocity = make_pin<double>(n + ".velocity", PinDir::Out);
      ch.velocity_rpm = make_pin<double>(n + ".velocity-rpm", PinDir::Out);
      ch.position_scale = make_pin<double>(n + ".position-scale", PinDir::IO, 1.0);
      ch.error = make_pin<bool>(n + ".error", PinDir::Out);
      ch.error_count = make_pin<uint32_t>(n + ".error-count", PinDir::Out);
    }
    export_method<&Encoder::update_counters>("encoder.update-counters", this, false);
    export_method<&Encoder::capture_position>("encoder.capture-position", this);
  }

  void update_counters(const rt::CycleInfo&) noexcept {
    for (auto& ch : channels_) ch.update_counters();
  }
  void capture_position(const rt::CycleInfo& info) noexcept {
    const double dt = cycle_seconds(info);
    for (auto& ch : channels_) ch.capture(dt);
  }

 private:
  struct Channel {
    BitPin phase_a, phase_b, phase_z, index_enable, reset, counter_mode, x4_mode, use_counts_in, error;
    S32Pin counts_in, rawcounts, count;
    FloatPin position, velocity, velocity_rpm, position_scale;
    U32Pin error_count;
    // Shared by the two functions; when they run in different threads the
    // count is read as one 32-bit atomic load (a cell), like LinuxCNC's.
    int32_t raw = 0;
    bool a = false, b = false, z = false, primed = false;
    int32_t last_counts_in = 0;
    bool counts_primed = false;
    int32_t index_offset = 0;   // raw at the last reset or index
    int32_t last_raw = 0;      // for velocity: raw counts see no reset or index jumps
    bool capture_primed = false;

    void update_counters() noexcept {
      if (use_counts_in.get()) {
        const int32_t c = counts_in.get();
        if (counts_primed) {
          // Modular difference: a wrapping 32-bit counter counts on.
          const auto delta = static_cast<int32_t>(static_cast<uint32_t>(c) - static_cast<uint32_t>(last_counts_in));
          raw = static_cast<int32_t>(static_cast<uint32_t>(raw) + static_cast<uint32_t>(delta));
        }
        last_counts_in = c;
        counts_primed = true;
        primed = false;
      } else {
        counts_primed = false;
        const bool na = phase_a.get(), nb = phase_b.get();
        if (!primed) {
          a = na;
          b = nb;
          primed = true;
        } else if (counter_mode.get()) {
          if (na && !a) ++raw;
        } else if (na != a && nb != b) {
          // Both phases changed between two samples: an edge was missed
          // and the direction is unknown. Count nothing, tell.
          error.set(true);
          error_count.set(error_count.get() + 1);
        } else if (na != a || nb != b) {
          // Forward (A leads B): the new A differs from the old B when A
          // changed, the new B equals the new A when B changed.
          const bool up = (na != a) ? (na != b) : (nb == na);
          if (x4_mode.get()) {
            raw += up ? 1 : -1;
          } else if (na != a && !nb) {
            // x1: one count per cycle, on A's edge while B is low (rising
            // forward, falling backward), so a reversal is consistent.
            raw += na ? 1 : -1;
          }
        }
        a = na;
        b = nb;
      }
      // Index: the first rising edge of Z while index-enable is TRUE zeroes
      // count and clears index-enable (motion's spindle sync and homing).
      const bool nz = phase_z.get();
      if (nz && !z && index_enable.get()) {
        index_offset = raw;
        index_enable.set(false);
      }
      z = nz;
      if (reset.get()) index_offset = raw;
      rawcounts.set(raw);
    }

    void capture(double dt) noexcept {
      const int32_t c = static_cast<int32_t>(static_cast<uint32_t>(rawcounts.get()) - static_cast<uint32_t>(index_offset));
      double scale = position_scale.get();
      if (scale == 0) scale = 1.0;  // a zero scale would divide by zero
      const int32_t r = rawcounts.get();
      if (capture_primed && dt > 0) {
        const auto delta = static_cast<int32_t>(static_cast<uint32_t>(r) - static_cast<uint32_t>(last_raw));
        velocity.set(static_cast<double>(delta) / scale / dt);
      } else {
        velocity.set(0);
      }
      capture_primed = true;
      last_raw = r;
      count.set(c);
      position.set(static_cast<double>(c) / scale);
      velocity_rpm.set(velocity.get() * 60.0);
    }
  };
  std::vector<Channel> channels_;
};

template <class Instance>
void add(ComponentRegistry& r, const std::string& comp, const std::string& prefix, const std::string& suffix,
         const std::string& help, const std::string& count_key = "count") {
  add_instances<Instance>(r, comp, prefix, help, count_key, suffix);
}

template <class In, class Out>
void add_conv(ComponentRegistry& r, const std::string& from, const std::string& to) {
  const std::string comp = "conv_" + from + "_" + to;
  const std::string prefix = "conv-" + from + "-" + to;
  add<Conv<In, Out>>(r, comp, prefix, "",
                     comp + " [count=N|names=a,b]: " + from + " in -> " + to + " out" +
                         (Conv<In, Out>::kCanOverflow ? " (out-of-range pin, clamp parameter)" : ""));
}

}  // namespace

void register_panel_components(ComponentRegistry& r) {
  add<Mux4>(r, "mux4", "mux4", "", "mux4 [count=N|names=a,b]: out = in[sel1*2+sel0]");
  add<Select8>(r, "select8", "select8", "", "select8 [count=N|names=a,b]: outN = enable AND sel == N");
  add<Toggle>(r, "toggle", "toggle", "", "toggle [count=N|names=a,b]: each debounced press of in inverts out");
  add<Edge>(r, "edge", "edge", "", "edge [count=N|names=a,b]: a pulse of out-width-ns on a rising/falling/any edge");
  add<Timedelay>(r, "timedelay", "timedelay", "",
                 "timedelay [count=N|names=a,b]: out follows in after on-delay/off-delay seconds");
  add<Limit3>(r, "limit3", "limit3", "",
              "limit3 [count=N|names=a,b]: out follows in within min/max, |v| <= maxv, |a| <= maxa");
  add<Pid>(r, "pid", "pid", ".do-pid-calcs",
           "pid [num_chan=N|names=a,b]: PID with feed-forward, deadband and limits (LinuxCNC's pid pins)", "num_chan");
  r.add("debounce", "debounce cfg=N[,N...]: groups of N filters, out follows in after `delay` cycles",
        [](ComponentContext& ctx, const LoadArgs& args) -> std::unique_ptr<Component> {
          return std::make_unique<Debounce>(ctx, args);
        });
  r.add("encoder",
        "encoder [num_chan=N|names=a,b]: quadrature/pulse counter from sampled inputs or a counter (counts-in)",
        [](ComponentContext& ctx, const LoadArgs& args) -> std::unique_ptr<Component> {
          return std::make_unique<Encoder>(ctx, args);
        });
  r.add("scope", "scope [samples=N]: samples up to 16 pins each cycle of scope.sample (halcmd scope ..., cnc-scope)",
        [](ComponentContext& ctx, const LoadArgs& args) -> std::unique_ptr<Component> {
          return std::make_unique<Scope>(ctx, args);
        });
  add_conv<double, int32_t>(r, "float", "s32");
  add_conv<int32_t, double>(r, "s32", "float");
  add_conv<bool, int32_t>(r, "bit", "s32");
  add_conv<bool, uint32_t>(r, "bit", "u32");
  add_conv<int32_t, bool>(r, "s32", "bit");
  add_conv<uint32_t, bool>(r, "u32", "bit");
  add_conv<double, uint32_t>(r, "float", "u32");
  add_conv<uint32_t, double>(r, "u32", "float");
  add_conv<int32_t, uint32_t>(r, "s32", "u32");
  add_conv<uint32_t, int32_t>(r, "u32", "s32");
}

}  // namespace cnc::hal
