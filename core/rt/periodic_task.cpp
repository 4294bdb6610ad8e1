#include "core/rt/periodic_task.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include "core/util/time.hpp"

namespace cnc::rt {
namespace {

bool realtime_disabled_by_env() {
  const char* v = std::getenv("CNC_NO_REALTIME");
  return v && *v && std::strcmp(v, "0") != 0;
}

RealtimeCapabilities probe() {
  RealtimeCapabilities caps;
  if (realtime_disabled_by_env()) {
    caps.note = "realtime disabled by CNC_NO_REALTIME: normal scheduling, memory not locked";
    return caps;
  }
  caps.memory_locked = ::mlockall(MCL_CURRENT | MCL_FUTURE) == 0;
  const int mlock_err = caps.memory_locked ? 0 : errno;
  // Probe SCHED_FIFO on a throw-away thread so this thread keeps its policy.
  int fifo_err = 0;
  std::thread t([&] {
    sched_param sp{};
    sp.sched_priority = sched_get_priority_min(SCHED_FIFO);
    fifo_err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
  });
  t.join();
  caps.fifo_scheduling = fifo_err == 0;
  std::string note;
  if (!caps.memory_locked) note += std::string("memory not locked (mlockall: ") + std::strerror(mlock_err) + ")";
  if (!caps.fifo_scheduling) {
    if (!note.empty()) note += "; ";
    note += std::string("SCHED_FIFO not permitted (") + std::strerror(fifo_err) + ")";
  }
  if (!note.empty()) {
    note += ": periodic threads run with normal scheduling and their timing will be poorer. "
            "Run as root, or grant CAP_SYS_NICE and CAP_IPC_LOCK (rtprio and memlock in limits.conf).";
  }
  caps.note = note;
  return caps;
}

}  // namespace

const RealtimeCapabilities& prepare_process() {
  static const RealtimeCapabilities caps = probe();
  return caps;
}

bool PeriodicTask::start(const Config& config, Callback callback, void* arg) {
  if (running_.load()) return false;
  if (thread_.joinable()) thread_.join();
  config_ = config;
  callback_ = callback;
  arg_ = arg;
  period_ns_ = config.period_ns;
  stats_.reset(period_ns_);
  stop_requested_.store(false);
  running_.store(true, std::memory_order_release);
  thread_ = std::thread([this] { loop(); });
  return true;
}

void PeriodicTask::stop() {
  stop_requested_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
  running_.store(false, std::memory_order_release);
}

void PeriodicTask::loop() {
  pthread_setname_np(pthread_self(), config_.name.substr(0, 15).c_str());
  const RealtimeCapabilities& caps = prepare_process();
  if (caps.fifo_scheduling) {
    sched_param sp{};
    sp.sched_priority = config_.priority >= 0 ? config_.priority : sched_get_priority_max(SCHED_FIFO) - 1;
    fifo_.store(pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) == 0, std::memory_order_relaxed);
  }
  // Touch the stack we will use so that page faults happen now, not in a cycle.
  {
    volatile char prefault[64 * 1024];
    for (std::size_t i = 0; i < sizeof prefault; i += 4096) prefault[i] = 0;
  }

  CycleInfo info;
  info.period_ns = period_ns_;
  info.periodic = true;
  int64_t next = monotonic_ns() + period_ns_;
  int64_t last_wake = 0;
  while (!stop_requested_.load(std::memory_order_acquire)) {
    next += phase_adjust_ns_.exchange(0, std::memory_order_relaxed);
    const timespec ts = to_timespec(next);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
    const int64_t now = monotonic_ns();
    info.now_ns = now;
    info.wake_latency_ns = now - next;
    info.actual_period_ns = last_wake == 0 ? period_ns_ : now - last_wake;
    stats_.record_wake(info.wake_latency_ns, info.actual_period_ns, last_wake == 0);
    last_wake = now;

    callback_(arg_, info);
    ++info.cycle;

    const int64_t done = monotonic_ns();
    stats_.record_exec(done - now);
    // Overrun: counted, and the grid is rejoined instead of bursting to
    // catch up; the next cycle is told (the motion controller acts on it).
    const CycleEnd end = end_cycle(next, done, period_ns_);
    stats_.record_cycle_end(end);
    info.missed_cycles = end.missed;
    info.overrun_streak = stats_.overrun_streak();
    next = end.next_ns;
  }
}

}  // namespace cnc::rt
