#include "sim/cia402/sim_host.hpp"

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>

#include "core/util/time.hpp"

namespace cnc::cia402::sim {
namespace {

// Words of a command without allocating: up to 6 of at most 31 characters.
struct Words {
  char w[6][32] = {};
  int n = 0;
  explicit Words(const char* s) {
    while (*s && n < 6) {
      while (*s == ' ' || *s == '\t') ++s;
      if (!*s) break;
      int k = 0;
      while (*s && *s != ' ' && *s != '\t') {
        if (k < 31) w[n][k++] = static_cast<char>(*s >= 'A' && *s <= 'Z' ? *s - 'A' + 'a' : *s);
        ++s;
      }
      w[n][k] = '\0';
      ++n;
    }
  }
  bool is(int i, const char* t) const { return i < n && std::strcmp(w[i], t) == 0; }
};

bool to_number(const char* s, double& out) {
  char* end = nullptr;
  out = std::strtod(s, &end);
  return end && end != s && *end == '\0';
}

}  // namespace

CanopenDrive& SimHost::add(const SimNodeConfig& config, std::unique_ptr<can::Transport> own) {
  drives_.push_back(std::make_unique<CanopenDrive>(config, own ? *own : transport_));
  any_shared_ = any_shared_ || !own;
  own_.push_back(std::move(own));
  own_last_frame_ns_.push_back(0);
  return *drives_.back();
}

CanopenDrive* SimHost::find(uint8_t node) noexcept {
  for (auto& d : drives_) {
    if (d->node_id() == node) return d.get();
  }
  return nullptr;
}

void SimHost::power_on(int64_t now_ns) {
  for (auto& d : drives_) d->start(now_ns);
}

void SimHost::step(int64_t now_ns) {
  Injection in;
  while (requests_.pop(in)) {
    Outcome out;
    out.serial = in.serial;
    apply(in, out.why);
    outcomes_.push(out);
  }
  if (any_shared_) {
    deliver(transport_, last_frame_ns_, nullptr, now_ns);
  } else {
    can::Frame unused;
    while (transport_.receive(unused)) {
    }  // every drive listens on its own transport: nobody reads this one
  }
  for (std::size_t i = 0; i < drives_.size(); ++i) {
    if (own_[i]) deliver(*own_[i], own_last_frame_ns_[i], drives_[i].get(), now_ns);
  }
  for (auto& d : drives_) d->poll(now_ns);
  if (after_pass) after_pass();
  passes_.fetch_add(1, std::memory_order_relaxed);
}

void SimHost::deliver(can::Transport& from, int64_t& last_frame_ns, CanopenDrive* only, int64_t now_ns) noexcept {
  can::Frame f;
  while (from.receive(f)) {
    // The frame's reception time is when the drive saw it: neither the
    // wake-up jitter of this thread nor a stall of this pass reaches the
    // drives. Frames that arrived while the pass ran are later than
    // `now_ns` (it was read when the pass began); they keep their own time,
    // or a backlog of SYNCs would all fall on one instant and each restart
    // the drives' interpolation with no time between them. Only a time
    // from another clock (none, or seconds away) is replaced by `now_ns`.
    int64_t t = f.timestamp_ns;
    if (t <= 0 || t < now_ns - kTrustedAgeNs || t > now_ns + kTrustedAgeNs) t = now_ns;
    t = std::max(t, last_frame_ns);  // never back in time (clock conversion jitter)
    last_frame_ns = t;
    if (only) {
      only->on_frame(f, t);
    } else {
      for (std::size_t i = 0; i < drives_.size(); ++i) {
        if (!own_[i]) drives_[i]->on_frame(f, t);
      }
    }
  }
}

void SimHost::start() {
  if (thread_.joinable()) return;
  power_on(transport_.now_ns());
  stop_.store(false);
  set_stepped_elsewhere(true);
  thread_ = std::thread([this] {
    // The simulated drives answer every SYNC within the cycle: ask for
    // SCHED_FIFO just below the servo thread (refused without privileges;
    // then the normal scheduler, as the controller's own threads do).
    if (!std::getenv("CNC_NO_REALTIME")) {
      sched_param p{};
      p.sched_priority = 60;
      pthread_setschedparam(pthread_self(), SCHED_FIFO, &p);
    }
    while (!stop_.load(std::memory_order_acquire)) {
      transport_.wait(1'000'000);  // SYNC wakes it at once; between SYNCs the drives keep time at 1 ms
      step(transport_.now_ns());
    }
  });
}

void SimHost::stop() {
  if (!thread_.joinable()) return;
  stop_.store(true);
  thread_.join();
  set_stepped_elsewhere(false);
}

std::string SimHost::inject(const std::string& command, double value, bool has_value) {
  std::lock_guard<std::mutex> lock(inject_mutex_);
  Injection in;
  in.text.assign(command);
  in.value = value;
  in.has_value = has_value;
  in.serial = ++serial_;
  if (!stepped_elsewhere_.load(std::memory_order_acquire)) {
    FixedString<200> why;
    apply(in, why);
    return std::string(why.view());
  }
  if (!requests_.push(in)) return "the simulator is busy";
  const int64_t deadline = monotonic_ns() + 2'000'000'000;
  Outcome out;
  while (monotonic_ns() < deadline) {
    while (outcomes_.pop(out)) {
      if (out.serial == in.serial) return std::string(out.why.view());
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return "the simulator did not answer within 2 s (is it stepped?)";
}

void SimHost::apply(const Injection& in, FixedString<200>& why) noexcept {
  why.assign("");
  const Words w(in.text.c_str());
  static constexpr const char* kUsage =
      "expected: drive <node> overcurrent | overtemperature [K] | following-error [N] | encoder-loss [1|0] | "
      "lost-frames [n] | refuse-sdo [1|0] | dead [1|0] | probe [1|0] | clear";
  if (w.n < 3 || !w.is(0, "drive")) {
    why.assign(kUsage);
    return;
  }
  double node = 0;
  if (!to_number(w.w[1], node) || node < 1 || node > 127 || node != static_cast<int>(node)) {
    why.format("\"%s\" is not a node-ID", w.w[1]);
    return;
  }
  CanopenDrive* d = find(static_cast<uint8_t>(node));
  if (!d) {
    why.format("no simulated drive with node-ID %d", static_cast<int>(node));
    return;
  }
  double value = in.value;
  bool has_value = in.has_value;
  if (!has_value && w.n > 3) has_value = to_number(w.w[3], value);  // "drive 1 lost-frames 20"
  DriveModel& m = d->model();
  const bool on = !has_value || value != 0;
  if (w.is(2, "overcurrent")) m.inject_overcurrent();
  else if (w.is(2, "overtemperature")) m.set_temperature_offset(has_value ? value : 60.0);
  else if (w.is(2, "following-error")) m.set_jam_force(has_value ? value : 20000.0);
  else if (w.is(2, "encoder-loss")) m.set_encoder_lost(on);
  else if (w.is(2, "lost-frames")) d->drop_frames(has_value ? static_cast<unsigned>(value < 0 ? 0 : value) : 10u);
  else if (w.is(2, "refuse-sdo")) m.set_refuse_writes(on);
  else if (w.is(2, "dead")) d->set_dead(on);
  else if (w.is(2, "probe")) m.plant().set_probe_override(on);
  else if (w.is(2, "clear")) {
    m.clear_injections();
    m.plant().set_probe_override(false);
    d->drop_frames(0);
    d->set_dead(false);
  } else {
    why.format("unknown injection \"%s\"; %s", w.w[2], kUsage);
  }
}

}  // namespace cnc::cia402::sim
