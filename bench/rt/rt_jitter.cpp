// Servo-thread timing with an empty function list: how late the thread
// wakes (latency) and how far the measured period strays from the nominal
// one. Prints figures; never fails on them.
//   bench_rt_jitter [seconds=10] [period_ns=1000000]
#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <thread>

#include "core/rt/periodic_task.hpp"

int main(int argc, char** argv) {
  const double seconds = argc > 1 ? std::atof(argv[1]) : 10.0;
  const int64_t period = argc > 2 ? std::atoll(argv[2]) : 1'000'000;
  const auto& caps = cnc::rt::prepare_process();
  cnc::rt::PeriodicTask task;
  task.start({"jitter", period, -1}, [](void*, const cnc::rt::CycleInfo&) {}, nullptr);
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  task.stop();
  const auto s = task.stats().snapshot();
  std::printf("servo thread, empty function list, period %" PRId64 " ns, %.1f s, %s, memory %s\n", period, seconds,
              task.uses_fifo() ? "SCHED_FIFO" : "normal scheduling", caps.memory_locked ? "locked" : "not locked");
  if (!caps.note.empty()) std::printf("  note: %s\n", caps.note.c_str());
  std::printf("  cycles %" PRIu64 ", overruns %" PRIu64 "\n", s.cycles, s.overruns);
  std::printf("  wake-up latency: min %.1f us, median %.1f us, p99 %.1f us, p99.9 %.1f us, max %.1f us\n",
              static_cast<double>(s.latency_min_ns) / 1e3, static_cast<double>(s.latency_percentile_ns(0.5)) / 1e3,
              static_cast<double>(s.latency_percentile_ns(0.99)) / 1e3,
              static_cast<double>(s.latency_percentile_ns(0.999)) / 1e3, static_cast<double>(s.latency_max_ns) / 1e3);
  std::printf("  measured period: min %.1f us, max %.1f us (nominal %.1f us)\n",
              static_cast<double>(s.actual_period_min_ns) / 1e3, static_cast<double>(s.actual_period_max_ns) / 1e3,
              static_cast<double>(period) / 1e3);
  return 0;
}
