// The panel building blocks of core/hal/panel_components.cpp: LinuxCNC's
// names, and their behaviour cycle by cycle.
#include <gtest/gtest.h>

#include <cmath>

#include "core/hal/commands.hpp"
#include "tests/support/testing.hpp"

using namespace cnc::hal;

namespace {
// A HAL with one 1 ms thread; `load` runs HAL lines, `step` runs cycles.
struct Bench {
  Hal hal;
  ComponentRegistry registry;
  CommandInterpreter interp{hal, registry, nullptr, nullptr};
  cnc::rt::CycleInfo info;
  Bench() {
    register_core_components(registry);
    interp.run_text("loadrt threads name1=t period1=1000000\n", "bench.hal");
    info.period_ns = info.actual_period_ns = 1'000'000;
  }
  void load(const std::string& text) { interp.run_text(text, "test.hal"); }
  void step(int n = 1) {
    for (int i = 0; i < n; ++i) {
      hal.find_thread("t")->run_cycle(info);
      ++info.cycle;
    }
  }
  void set(const std::string& name, const std::string& v) { hal.set_value(name, v); }
  std::string get(const std::string& name) const { return hal.get_value(name); }
  double num(const std::string& name) const { return std::stod(hal.get_value(name)); }
  bool bit(const std::string& name) const { return hal.get_value(name) == "TRUE"; }
};
}  // namespace

TEST(PanelComponents, Mux4SelectsTheInputNumberedBySel1Sel0) {
  Bench b;
  b.load("loadrt mux4\naddf mux4.0 t\nsetp mux4.0.in0 10\nsetp mux4.0.in1 11\nsetp mux4.0.in2 12\nsetp mux4.0.in3 13\n");
  for (int s = 0; s < 4; ++s) {
    b.set("mux4.0.sel0", (s & 1) ? "1" : "0");
    b.set("mux4.0.sel1", (s & 2) ? "1" : "0");
    b.step();
    EXPECT_EQ(b.num("mux4.0.out"), 10 + s);
  }
}

TEST(PanelComponents, Select8RaisesOnlyTheSelectedOutputWhileEnabled) {
  Bench b;
  b.load("loadrt select8\naddf select8.0 t\nsetp select8.0.sel 5\n");
  b.step();
  for (int i = 0; i < 8; ++i) EXPECT_EQ(b.bit("select8.0.out" + std::to_string(i)), i == 5) << i;
  b.set("select8.0.enable", "0");
  b.step();
  EXPECT_FALSE(b.bit("select8.0.out5"));
  b.set("select8.0.enable", "1");
  b.set("select8.0.sel", "9");
  b.step();
  for (int i = 0; i < 8; ++i) EXPECT_FALSE(b.bit("select8.0.out" + std::to_string(i)));
}

TEST(PanelComponents, DebounceNeedsDelayCyclesOfSteadyInput) {
  Bench b;
  b.load("loadrt debounce cfg=2,1\naddf debounce.0 t\naddf debounce.1 t\nsetp debounce.0.delay 3\n");
  EXPECT_EQ(b.get("debounce.1.delay"), "5") << "LinuxCNC's default";
  b.set("debounce.0.1.in", "1");
  b.step(2);
  EXPECT_FALSE(b.bit("debounce.0.1.out"));
  b.step();
  EXPECT_TRUE(b.bit("debounce.0.1.out")) << "after 3 cycles";
  // A one-cycle glitch low does not drop it.
  b.set("debounce.0.1.in", "0");
  b.step();
  b.set("debounce.0.1.in", "1");
  b.step();
  EXPECT_TRUE(b.bit("debounce.0.1.out"));
  b.set("debounce.0.1.in", "0");
  b.step(2);
  EXPECT_TRUE(b.bit("debounce.0.1.out"));
  b.step();
  EXPECT_FALSE(b.bit("debounce.0.1.out"));
  EXPECT_FALSE(b.bit("debounce.0.0.out")) << "filters are independent";
}

TEST(PanelComponents, DebounceNeedsAConfiguration) {
  Bench b;
  EXPECT_THROW(b.load("loadrt debounce\n"), std::runtime_error);
  EXPECT_THROW(b.load("loadrt debounce cfg=0\n"), std::runtime_error);
}

TEST(PanelComponents, ToggleInvertsOnEachDebouncedPress) {
  Bench b;
  b.load("loadrt toggle\naddf toggle.0 t\n");
  b.set("toggle.0.in", "1");
  b.step();
  EXPECT_FALSE(b.bit("toggle.0.out")) << "debounce 2: one cycle is not a press";
  b.step();
  EXPECT_TRUE(b.bit("toggle.0.out"));
  b.step(10);
  EXPECT_TRUE(b.bit("toggle.0.out")) << "holding the button does not toggle again";
  b.set("toggle.0.in", "0");
  b.step(3);
  b.set("toggle.0.in", "1");
  b.step(3);
  EXPECT_FALSE(b.bit("toggle.0.out"));
}

TEST(PanelComponents, EdgePulsesOnTheChosenEdgeForOutWidth) {
  Bench b;
  b.load("loadrt edge count=2\naddf edge.0 t\naddf edge.1 t\nsetp edge.1.both 1\nsetp edge.0.out-width-ns 2500000\n");
  b.step();
  EXPECT_FALSE(b.bit("edge.0.out"));
  EXPECT_TRUE(b.bit("edge.0.out-invert"));
  b.set("edge.0.in", "1");
  b.set("edge.1.in", "1");
  b.step();
  EXPECT_TRUE(b.bit("edge.0.out"));
  EXPECT_FALSE(b.bit("edge.0.out-invert"));
  EXPECT_TRUE(b.bit("edge.1.out"));
  b.step();
  EXPECT_TRUE(b.bit("edge.0.out")) << "2.5 ms wide";
  EXPECT_FALSE(b.bit("edge.1.out")) << "width 0: one cycle";
  b.step(2);
  EXPECT_FALSE(b.bit("edge.0.out"));
  b.set("edge.0.in", "0");
  b.set("edge.1.in", "0");
  b.step();
  EXPECT_FALSE(b.bit("edge.0.out")) << "in-edge TRUE: rising only";
  EXPECT_TRUE(b.bit("edge.1.out")) << "both";
  b.set("edge.0.in-edge", "0");
  b.set("edge.0.in", "1");
  b.step();
  b.set("edge.0.in", "0");
  b.step();
  EXPECT_TRUE(b.bit("edge.0.out")) << "in-edge FALSE: falling";
}

TEST(PanelComponents, TimedelayWaitsOnAndOffDelay) {
  Bench b;
  b.load("loadrt timedelay\naddf timedelay.0 t\nsetp timedelay.0.on-delay 0.005\nsetp timedelay.0.off-delay 0.002\n");
  b.set("timedelay.0.in", "1");
  b.step(4);
  EXPECT_FALSE(b.bit("timedelay.0.out"));
  EXPECT_NEAR(b.num("timedelay.0.elapsed"), 0.004, 1e-9);
  b.step();
  EXPECT_TRUE(b.bit("timedelay.0.out"));
  b.set("timedelay.0.in", "0");
  b.step();
  EXPECT_TRUE(b.bit("timedelay.0.out"));
  b.step();
  EXPECT_FALSE(b.bit("timedelay.0.out"));
}

TEST(PanelComponents, Limit3NeverExceedsMaxvMaxaAndStopsOnTheLimit) {
  Bench b;
  b.load("loadrt limit3\naddf limit3.0 t\nsetp limit3.0.min -5\nsetp limit3.0.max 20\n"
         "setp limit3.0.maxv 100\nsetp limit3.0.maxa 1000\nsetp limit3.0.in 50\n");
  const double dt = 0.001;
  double pos = 0, vel = 0, vmax_seen = 0, amax_seen = 0, highest = 0;
  for (int i = 0; i < 2000; ++i) {
    if (i == 1000) b.set("limit3.0.in", "-50");  // reverse at full speed
    b.step();
    const double p = b.num("limit3.0.out");
    const double v = (p - pos) / dt;
    vmax_seen = std::max(vmax_seen, std::fabs(v));
    amax_seen = std::max(amax_seen, std::fabs(v - vel) / dt);
    highest = std::max(highest, p);
    pos = p;
    vel = v;
    if (i == 999) {
      EXPECT_DOUBLE_EQ(p, 20.0) << "arrived on max";
    }
  }
  EXPECT_LE(vmax_seen, 100.0 + 1e-6);
  EXPECT_LE(amax_seen, 1000.0 + 1e-3);
  EXPECT_LE(highest, 20.0 + 1e-9) << "no overshoot past max";
  EXPECT_DOUBLE_EQ(pos, -5.0);
  EXPECT_NEAR(vmax_seen, 100.0, 1e-6) << "reached maxv on the long move";
}

TEST(PanelComponents, Limit3LoadJumpsToTheClampedInput) {
  Bench b;
  b.load("loadrt limit3\naddf limit3.0 t\nsetp limit3.0.max 3\nsetp limit3.0.maxv 1\nsetp limit3.0.in 7\n"
         "setp limit3.0.load 1\n");
  b.step();
  EXPECT_EQ(b.num("limit3.0.out"), 3.0);
}

TEST(PanelComponents, Limit3DisabledReturnsToZeroWithinItsLimits) {
  Bench b;
  b.load("loadrt limit3\naddf limit3.0 t\nsetp limit3.0.maxv 1000\nsetp limit3.0.in 5\nsetp limit3.0.load 1\n");
  EXPECT_EQ(b.get("limit3.0.enable"), "TRUE") << "LinuxCNC's default";
  b.step();
  EXPECT_EQ(b.num("limit3.0.out"), 5.0);
  b.load("setp limit3.0.load 0\nsetp limit3.0.enable 0\n");
  b.step();
  EXPECT_NEAR(b.num("limit3.0.out"), 4.0, 1e-9) << "at most maxv * 1 ms per cycle";
  b.step(10);
  EXPECT_EQ(b.num("limit3.0.out"), 0.0);
}

TEST(PanelComponents, LinuxCncLoadArgumentsAndParameters) {
  Bench b;
  b.load("loadrt pid num_chan=2\nloadrt siggen num_chan=1\nloadrt sum2\nloadrt lowpass\naddf siggen.0.update t\n");
  EXPECT_TRUE(b.hal.has_pin("pid.1.Pgain"));
  EXPECT_TRUE(b.hal.has_param("sum2.0.gain0")) << "parameters, as LinuxCNC's";
  EXPECT_TRUE(b.hal.has_param("sum2.0.offset"));
  EXPECT_TRUE(b.hal.has_param("lowpass.0.gain"));
  EXPECT_ANY_THROW(b.load("loadrt pid count=1\n")) << "LinuxCNC's pid takes num_chan=";
}

TEST(PanelComponents, SiggenResetHoldsTheDocumentedStates) {
  Bench b;
  b.load("loadrt siggen\naddf siggen.0.update t\nsetp siggen.0.amplitude 2\nsetp siggen.0.frequency 100\n");
  b.step(3);
  b.set("siggen.0.reset", "1");
  b.step();
  EXPECT_EQ(b.num("siggen.0.sine"), 0.0);
  EXPECT_EQ(b.num("siggen.0.sawtooth"), 0.0);
  EXPECT_EQ(b.num("siggen.0.square"), -2.0);
  EXPECT_EQ(b.num("siggen.0.cosine"), -2.0);
  EXPECT_EQ(b.num("siggen.0.triangle"), -2.0);
}

TEST(PanelComponents, PidOutputForKnownInputs) {
  Bench b;
  b.load("loadrt pid names=px\naddf px.do-pid-calcs t\n"
         "setp px.Pgain 2\nsetp px.Igain 10\nsetp px.Dgain 0.01\nsetp px.FF1 1\nsetp px.bias 0.5\n"
         "setp px.command 1\nsetp px.feedback 0.75\n");
  b.step();
  EXPECT_EQ(b.num("px.output"), 0.0) << "disabled: output 0";
  EXPECT_EQ(b.num("px.error"), 0.25);
  b.set("px.enable", "1");
  b.step();
  // e = 0.25, errorI = 0.25 * 0.001, errorD = (0.25 - 0.25)/dt = 0 (the
  // previous cycle saw the same error), command steady: FF1 term 0.
  EXPECT_NEAR(b.num("px.output"), 0.5 + 2 * 0.25 + 10 * 0.25e-3, 1e-12);
  // The command moves 0.001 per cycle: FF1 adds 1 (units/s), the error
  // grows by 0.001 per cycle: D adds 0.01 * 1.
  b.set("px.command", "1.001");
  b.step();
  EXPECT_NEAR(b.num("px.commandD"), 1.0, 1e-9);
  EXPECT_NEAR(b.num("px.output"), 0.5 + 2 * 0.251 + 10 * (0.25e-3 + 0.251e-3) + 0.01 * 1.0 + 1.0, 1e-9);
}

TEST(PanelComponents, PidDeadbandAndMaxoutputSaturate) {
  Bench b;
  b.load("loadrt pid\naddf pid.0.do-pid-calcs t\nsetp pid.0.enable 1\nsetp pid.0.deadband 0.1\n"
         "setp pid.0.maxoutput 5\nsetp pid.0.command 0.05\n");
  b.step();
  EXPECT_EQ(b.num("pid.0.output"), 0.0) << "inside the deadband";
  b.set("pid.0.command", "100");
  b.step(3);
  EXPECT_EQ(b.num("pid.0.output"), 5.0);
  EXPECT_TRUE(b.bit("pid.0.saturated"));
  EXPECT_EQ(b.get("pid.0.saturated-count"), "3");
}

// Moves a quadrature signal `edges` edges, one per cycle; `phase` is where
// the signal is (0 at A = B = 0).
void quadrature(Bench& b, const std::string& enc, int& phase, int edges, bool forward) {
  // States in forward order: 00 10 11 01 (A leads B).
  static const int kA[4] = {0, 1, 1, 0}, kB[4] = {0, 0, 1, 1};
  for (int i = 0; i < edges; ++i) {
    phase = (phase + (forward ? 1 : 3)) % 4;
    b.set(enc + ".phase-A", kA[phase] ? "1" : "0");
    b.set(enc + ".phase-B", kB[phase] ? "1" : "0");
    b.step();
  }
}

TEST(PanelComponents, EncoderCountsQuadratureBothDirectionsInX4AndX1) {
  Bench b;
  b.load("loadrt encoder num_chan=1\naddf encoder.update-counters t\naddf encoder.capture-position t\n"
         "setp encoder.0.position-scale 4\n");
  b.step();
  int ph = 0;
  quadrature(b, "encoder.0", ph, 40, true);
  EXPECT_EQ(b.get("encoder.0.counts"), "40");
  EXPECT_EQ(b.num("encoder.0.position"), 10.0);
  EXPECT_EQ(b.num("encoder.0.velocity"), 250.0) << "one count per ms over scale 4";
  quadrature(b, "encoder.0", ph, 48, false);
  EXPECT_EQ(b.get("encoder.0.counts"), "-8");
  EXPECT_EQ(b.num("encoder.0.velocity"), -250.0);
  b.set("encoder.0.x4-mode", "0");
  quadrature(b, "encoder.0", ph, 40, true);
  EXPECT_EQ(b.get("encoder.0.counts"), "2") << "x1: one count per 4 edges";
  quadrature(b, "encoder.0", ph, 40, false);
  EXPECT_EQ(b.get("encoder.0.counts"), "-8") << "and back to the same count";
  EXPECT_FALSE(b.bit("encoder.0.error"));
}

TEST(PanelComponents, EncoderReportsBothPhasesChangingInOneSample) {
  Bench b;
  b.load("loadrt encoder num_chan=1\naddf encoder.update-counters t\naddf encoder.capture-position t\n");
  b.step();
  b.set("encoder.0.phase-A", "1");
  b.set("encoder.0.phase-B", "1");
  b.step();
  EXPECT_TRUE(b.bit("encoder.0.error"));
  EXPECT_EQ(b.get("encoder.0.error-count"), "1");
  EXPECT_EQ(b.get("encoder.0.counts"), "0") << "a skipped edge is not guessed";
}

TEST(PanelComponents, EncoderCounterModeCountsRisingEdgesOfA) {
  Bench b;
  b.load("loadrt encoder names=mpg\naddf encoder.update-counters t\naddf encoder.capture-position t\n"
         "setp mpg.counter-mode 1\n");
  b.step();  // the first sample is the inputs' rest state
  for (int i = 0; i < 10; ++i) {
    b.set("mpg.phase-A", (i % 2) ? "0" : "1");
    b.set("mpg.phase-B", (i % 3) ? "0" : "1");  // ignored
    b.step();
  }
  EXPECT_EQ(b.get("mpg.counts"), "5");
}

TEST(PanelComponents, EncoderIndexAndResetZeroTheCount) {
  Bench b;
  b.load("loadrt encoder num_chan=1\naddf encoder.update-counters t\naddf encoder.capture-position t\n");
  b.step();
  int ph = 0;
  quadrature(b, "encoder.0", ph, 10, true);
  b.set("encoder.0.phase-Z", "1");
  b.step();
  EXPECT_EQ(b.get("encoder.0.counts"), "10") << "index-enable FALSE: Z ignored";
  b.set("encoder.0.phase-Z", "0");
  b.set("encoder.0.index-enable", "1");
  quadrature(b, "encoder.0", ph, 3, true);
  b.set("encoder.0.phase-Z", "1");
  b.step();
  EXPECT_EQ(b.get("encoder.0.counts"), "0");
  EXPECT_FALSE(b.bit("encoder.0.index-enable"));
  EXPECT_EQ(b.get("encoder.0.rawcounts"), "13");
  quadrature(b, "encoder.0", ph, 2, true);
  b.set("encoder.0.reset", "1");
  b.step();
  EXPECT_EQ(b.get("encoder.0.counts"), "0");
}

TEST(PanelComponents, EncoderTakesAWrappingCounterOnCountsIn) {
  Bench b;
  b.load("loadrt encoder num_chan=1\naddf encoder.update-counters t\naddf encoder.capture-position t\n"
         "setp encoder.0.use-counts-in 1\nsetp encoder.0.counts-in 2147483640\n");
  b.step();
  EXPECT_EQ(b.get("encoder.0.counts"), "0") << "the counter's value at start is the origin";
  b.set("encoder.0.counts-in", "-2147483646");  // wrapped: +10
  b.step();
  EXPECT_EQ(b.get("encoder.0.counts"), "10");
  EXPECT_EQ(b.num("encoder.0.velocity"), 10000.0);
}

TEST(PanelComponents, ConvClampsOrWrapsAndTellsOutOfRange) {
  Bench b;
  b.load("loadrt conv_float_s32 count=2\nloadrt conv_s32_u32\nloadrt conv_u32_s32\nloadrt conv_s32_bit\n"
         "loadrt conv_bit_s32\nloadrt conv_s32_float\nloadrt conv_float_u32\nloadrt conv_u32_float\n"
         "loadrt conv_bit_u32\nloadrt conv_u32_bit\n"
         "addf conv-float-s32.0 t\naddf conv-float-s32.1 t\naddf conv-s32-u32.0 t\naddf conv-u32-s32.0 t\n"
         "addf conv-s32-bit.0 t\naddf conv-float-u32.0 t\n"
         "setp conv-float-s32.0.in -2.7\nsetp conv-float-s32.1.in 3e9\nsetp conv-s32-u32.0.in -5\n"
         "setp conv-u32-s32.0.in 4000000000\nsetp conv-s32-bit.0.in 7\nsetp conv-float-u32.0.in -1\n");
  EXPECT_FALSE(b.hal.has_param("conv-s32-float.0.clamp")) << "no range to leave";
  EXPECT_EQ(b.get("conv-float-s32.0.clamp"), "FALSE") << "LinuxCNC's default: wrap";
  b.load("setp conv-float-s32.1.clamp 1\nsetp conv-s32-u32.0.clamp 1\nsetp conv-u32-s32.0.clamp 1\n"
         "setp conv-s32-bit.0.clamp 1\nsetp conv-float-u32.0.clamp 1\n");
  EXPECT_FALSE(b.hal.has_pin("conv-bit-s32.0.out-of-range"));
  b.step();
  EXPECT_EQ(b.get("conv-float-s32.0.out"), "-2") << "truncation toward zero";
  EXPECT_FALSE(b.bit("conv-float-s32.0.out-of-range"));
  EXPECT_EQ(b.get("conv-float-s32.1.out"), "2147483647");
  EXPECT_TRUE(b.bit("conv-float-s32.1.out-of-range"));
  EXPECT_EQ(b.get("conv-s32-u32.0.out"), "0");
  EXPECT_TRUE(b.bit("conv-s32-u32.0.out-of-range"));
  EXPECT_EQ(b.get("conv-u32-s32.0.out"), "2147483647");
  EXPECT_TRUE(b.bit("conv-s32-bit.0.out-of-range"));
  EXPECT_EQ(b.get("conv-s32-bit.0.out"), "TRUE");
  EXPECT_EQ(b.get("conv-float-u32.0.out"), "0");
  b.load("setp conv-float-s32.1.clamp 0\nsetp conv-s32-u32.0.clamp 0\nsetp conv-u32-s32.0.clamp 0\n");
  b.step();
  EXPECT_EQ(b.get("conv-float-s32.1.out"), "-1294967296") << "wraps as a C cast";
  EXPECT_EQ(b.get("conv-s32-u32.0.out"), "4294967291");
  EXPECT_EQ(b.get("conv-u32-s32.0.out"), "-294967296");
}

TEST(PanelComponents, UpperCaseLinuxCncPinNamesAreAccepted) {
  EXPECT_EQ(check_pin_name("pid.0.FF0"), "");
  EXPECT_EQ(check_pin_name("encoder.0.phase-A"), "");
  EXPECT_NE(check_pin_name("pid_0.FF0"), "");
  EXPECT_NE(check_name("pid.0.FF0"), "") << "functions and threads stay lower case";
}

TEST(PanelComponents, ServoCycleDoesNotAllocate) {
  if (!cnc::testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counter off in sanitizer builds";
  Bench b;
  b.load("loadrt mux4\nloadrt select8\nloadrt debounce cfg=4\nloadrt toggle\nloadrt edge\nloadrt timedelay\n"
         "loadrt limit3\nloadrt pid\nloadrt encoder num_chan=2\nloadrt conv_float_s32\nloadrt conv_s32_bit\n"
         "loadrt siggen\n"
         "net s siggen.0.sine => limit3.0.in pid.0.command mux4.0.in1 conv-float-s32.0.in\n"
         "net c siggen.0.clock => debounce.0.0.in toggle.0.in edge.0.in timedelay.0.in encoder.0.phase-A "
         "mux4.0.sel0\n"
         "net i conv-float-s32.0.out => select8.0.sel conv-s32-bit.0.in\n"
         "setp encoder.0.counter-mode 1\nsetp pid.0.enable 1\nsetp siggen.0.frequency 50\nsetp timedelay.0.on-delay 0.001\n");
  for (const char* f : {"siggen.0.update", "mux4.0", "select8.0", "debounce.0", "toggle.0", "edge.0", "timedelay.0",
                        "limit3.0", "pid.0.do-pid-calcs", "encoder.update-counters", "encoder.capture-position",
                        "conv-float-s32.0", "conv-s32-bit.0"}) {
    b.hal.add_function(f, "t");
  }
  cnc::testing::ScopedAllocationCheck check;
  b.step(5000);
  EXPECT_EQ(check.allocations(), 0u);
  EXPECT_NE(b.get("encoder.0.rawcounts"), "0") << "the functions really ran";
}
