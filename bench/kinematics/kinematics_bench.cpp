// kinematics_bench: forward and inverse call times of every kinematics
// module, loaded as the controller loads them (`loadrt`, geometry on HAL
// pins), on a smooth machine trajectory sampled every 1 ms so that each
// inverse starts from the previous cycle's joints, as in the servo thread.
//
// Method: every call is timed on its own with the CPU's time-stamp counter
// (rdtsc fenced by lfence on x86-64, calibrated against steady_clock;
// steady_clock elsewhere); the timer's own cost (its median) is subtracted.
// Reported: median, 99th and 99.9th percentile over N calls (default 20000) and
// the maximum. Single calls keep the percentile about the code: batches of
// calls would be hit by interrupts and preemption many times more often.
// Goals (issue 9): closed-form 5-axis inverse <= 0.2 us; serial-arm
// iterative inverse <= 20 us from the previous cycle's joints.
//
// Usage: kinematics_bench [calls]   (taskset -c N for steadier tails)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#if defined(__x86_64__)
#include <x86intrin.h>
#endif

#include "core/hal/commands.hpp"
#include "core/hal/hal.hpp"
#include "kinematics/kinematics.hpp"

using namespace cnc;
using namespace cnc::kin;
using Clock = std::chrono::steady_clock;

namespace {

volatile double g_sink = 0;  // keeps results alive

// Ticks of the timer: TSC cycles on x86-64, nanoseconds elsewhere.
inline uint64_t ticks() noexcept {
#if defined(__x86_64__)
  _mm_lfence();
  const uint64_t t = __rdtsc();
  _mm_lfence();
  return t;
#else
  return static_cast<uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count());
#endif
}

struct Timer {
  double per_ns;       // ticks per nanosecond
  double overhead_ns;  // median cost of reading the timer twice
};

Timer calibrate() {
  Timer t{1.0, 0.0};
#if defined(__x86_64__)
  const auto c0 = Clock::now();
  const uint64_t k0 = ticks();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const uint64_t k1 = ticks();
  const auto c1 = Clock::now();
  t.per_ns = static_cast<double>(k1 - k0) / std::chrono::duration<double, std::nano>(c1 - c0).count();
#endif
  std::vector<double> v(20000);
  for (double& x : v) {
    const uint64_t a = ticks();
    const uint64_t b = ticks();
    x = static_cast<double>(b - a) / t.per_ns;
  }
  std::sort(v.begin(), v.end());
  t.overhead_ns = v[v.size() / 2];
  return t;
}

struct Stats {
  double median_us, p99_us, p999_us, max_us;
};

// Times `calls` single calls of `call(i)`; per-call statistics.
Stats measure(int calls, std::size_t samples, const Timer& timer, const std::function<void(std::size_t)>& call) {
  std::vector<double> ns(static_cast<std::size_t>(calls));
  std::size_t i = 0;
  for (int w = 0; w < 2000; ++w) call(i++ % samples);  // warm caches and branch predictors
  for (double& x : ns) {
    const std::size_t s = i++ % samples;
    const uint64_t t0 = ticks();
    call(s);
    const uint64_t t1 = ticks();
    x = std::max(0.0, static_cast<double>(t1 - t0) / timer.per_ns - timer.overhead_ns);
  }
  std::sort(ns.begin(), ns.end());
  const auto at = [&](double q) { return ns[static_cast<std::size_t>(q * static_cast<double>(ns.size() - 1))]; };
  return {at(0.5) / 1000.0, at(0.99) / 1000.0, at(0.999) / 1000.0, ns.back() / 1000.0};
}

struct Module {
  const char* label;
  const char* load;
  std::vector<const char*> setp;
  double goal_inverse_us;  // 0: none
};

// A smooth 1 ms trajectory in joint space around a working posture.
std::vector<std::vector<double>> joint_path(int n, std::size_t samples) {
  std::vector<std::vector<double>> path(samples, std::vector<double>(static_cast<std::size_t>(n)));
  const double base[9] = {12, -25, 40, 15, 35, -20, 1, 2, 3};
  for (std::size_t s = 0; s < samples; ++s) {
    const double t = static_cast<double>(s) * 0.001;
    for (int j = 0; j < n; ++j) {
      path[s][static_cast<std::size_t>(j)] = base[j % 9] + 20.0 * std::sin(t * (1.0 + 0.3 * j) + j);
    }
  }
  return path;
}

void bench_module(const Module& m, int calls, const Timer& timer) {
  hal::Hal hal;
  hal::ComponentRegistry registry;
  register_kinematics_components(registry);
  hal::CommandInterpreter interp(hal, registry, nullptr, nullptr);
  interp.execute(std::string("loadrt ") + m.load);
  for (const char* s : m.setp) interp.execute(std::string("setp ") + s);
  Kinematics* k = nullptr;
  for (hal::Component* c : hal.components()) {
    if (auto* kc = dynamic_cast<KinematicsComponent*>(c)) k = &kc->kinematics();
  }
  if (k == nullptr) return;

  constexpr std::size_t kSamples = 4096;
  const auto path = joint_path(k->num_joints(), kSamples);
  std::vector<Pose> poses(kSamples);
  for (std::size_t s = 0; s < kSamples; ++s) {
    if (k->forward(path[s].data(), poses[s]) != KinResult::Ok) {
      std::printf("%-16s forward failed on the benchmark path\n", m.label);
      return;
    }
  }

  const Stats fwd = measure(calls, kSamples, timer, [&](std::size_t s) {
    Pose p;
    k->forward(path[s].data(), p);
    g_sink = g_sink + p[0];
  });
  // Inverse from the previous sample's joints, as the servo thread calls it.
  int failures = 0;
  const Stats inv = measure(calls, kSamples, timer, [&](std::size_t s) {
    double out[kMaxJoints];
    const double* hint = path[s == 0 ? kSamples - 1 : s - 1].data();
    if (k->inverse(poses[s], hint, out) != KinResult::Ok) ++failures;
    g_sink = g_sink + out[0];
  });

  const auto row = [&](const char* call, const Stats& st, double goal) {
    std::printf("%-16s %-8s %10.3f %10.3f %10.3f %10.3f", m.label, call, st.median_us, st.p99_us, st.p999_us,
                st.max_us);
    if (goal > 0) {
      std::printf("   goal <= %g us: median %s, p99.9 %s", goal, st.median_us <= goal ? "met" : "MISSED",
                  st.p999_us <= goal ? "met" : "MISSED");
    }
    std::printf("\n");
  };
  row("forward", fwd, 0);
  row("inverse", inv, m.goal_inverse_us);
  if (failures != 0) std::printf("%-16s inverse failed %d times on the benchmark path\n", m.label, failures);
}

}  // namespace

int main(int argc, char** argv) {
  const int calls = argc > 1 ? std::max(1000, std::atoi(argv[1])) : 20000;
  const Timer timer = calibrate();
  const std::vector<Module> modules = {
      {"trivkins", "trivkins coordinates=XYZ", {}, 0},
      {"trivkins-gantry", "trivkins coordinates=XYYZ kinstype=B", {}, 0},
      {"matrixkins", "matrixkins c-xy=0.0002 c-yx=-0.0001 c-zz=1.0001", {}, 0},
      {"xyzac-trt-kins", "xyzac-trt-kins z-rot-point=-120 y-offset=3.5 z-offset=-40 tool-offset=55", {}, 0.2},
      {"xyzbc-trt-kins", "xyzbc-trt-kins z-rot-point=-120 x-offset=-6 z-offset=-35 tool-offset=55", {}, 0.2},
      {"headtable-kins", "headtable-kins pivot-length=150 tool-offset=55", {}, 0.2},
      {"scarakins", "scarakins", {}, 0},
      {"genserkins", "genserkins a-1=85 a-2=380 a-3=100 d-0=350 d-3=425 d-5=100",
       {"genserkins.alpha-1 -1.5707963267948966", "genserkins.alpha-3 -1.5707963267948966",
        "genserkins.alpha-4 1.5707963267948966", "genserkins.alpha-5 -1.5707963267948966"},
       20},
  };
  std::printf("kinematics call times (us per call), %d calls each, timer cost %.1f ns subtracted\n", calls,
              timer.overhead_ns);
  std::printf("%-16s %-8s %10s %10s %10s %10s\n", "module", "call", "median", "p99", "p99.9", "max");
  // What the harness itself shows for a call that does nothing: the floor
  // under every figure (timer resolution, interrupts, a VM's jitter).
  const Stats floor = measure(calls, 1, timer, [](std::size_t s) { g_sink = g_sink + static_cast<double>(s); });
  std::printf("%-16s %-8s %10.3f %10.3f %10.3f %10.3f\n", "(timer floor)", "empty", floor.median_us, floor.p99_us,
              floor.p999_us, floor.max_us);
  for (const Module& m : modules) bench_module(m, calls, timer);
  return 0;
}
