#include "cia402/sim/sim_host.hpp"

#include <pthread.h>
#include <sched.h>

#include <cstdlib>
#include <future>

#include "core/util/strings.hpp"
#include "core/util/time.hpp"

namespace cnc::cia402::sim {

CanopenDrive& SimHost::add(const SimNodeConfig& config) {
  drives_.push_back(std::make_unique<CanopenDrive>(config, transport_));
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
  std::vector<std::function<void()>> calls;
  {
    std::lock_guard<std::mutex> lock(calls_mutex_);
    calls.swap(calls_);
  }
  for (auto& f : calls) f();
  can::Frame f;
  while (transport_.receive(f)) {
    // The frame's reception time is when the drive saw it (SYNC jitter of
    // this thread's wake-up does not reach the plant).
    const int64_t t = f.timestamp_ns > 0 && f.timestamp_ns <= now_ns ? f.timestamp_ns : now_ns;
    for (auto& d : drives_) d->on_frame(f, t);
  }
  for (auto& d : drives_) d->poll(now_ns);
  if (after_pass) after_pass();
  passes_.fetch_add(1, std::memory_order_relaxed);
}

void SimHost::start() {
  if (thread_.joinable()) return;
  power_on(monotonic_ns());
  stop_.store(false);
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
      transport_.wait(250'000);
      step(monotonic_ns());
    }
  });
}

void SimHost::stop() {
  if (!thread_.joinable()) return;
  stop_.store(true);
  thread_.join();
}

void SimHost::call(std::function<void()> f) {
  if (!thread_.joinable()) {
    f();
    return;
  }
  std::lock_guard<std::mutex> lock(calls_mutex_);
  calls_.push_back(std::move(f));
}

std::string SimHost::inject(const std::string& command, double value, bool has_value) {
  if (!thread_.joinable()) return apply(command, value, has_value);
  auto done = std::make_shared<std::promise<std::string>>();
  auto result = done->get_future();
  call([this, command, value, has_value, done] { done->set_value(apply(command, value, has_value)); });
  if (result.wait_for(std::chrono::seconds(2)) != std::future_status::ready) return "the simulator did not answer";
  return result.get();
}

std::string SimHost::apply(const std::string& command, double value, bool has_value) {
  const auto words = split_blanks(command);
  auto usage = [] {
    return std::string(
        "expected: drive <node> overcurrent | overtemperature [K] | following-error [N] | encoder-loss [1|0] | "
        "lost-frames [n] | refuse-sdo [1|0] | dead [1|0] | probe [1|0] | clear");
  };
  if (words.size() < 3 || !iequals(words[0], "drive")) return usage();
  const auto node = parse_int(words[1]);
  if (!node || *node < 1 || *node > 127) return "\"" + words[1] + "\" is not a node-ID";
  CanopenDrive* d = find(static_cast<uint8_t>(*node));
  if (!d) return "no simulated drive with node-ID " + words[1];
  // A value may also follow the words ("drive 1 lost-frames 20").
  if (!has_value && words.size() > 3) {
    if (const auto v = parse_double(words[3])) {
      value = *v;
      has_value = true;
    }
  }
  const std::string what = to_lower(words[2]);
  DriveModel& m = d->model();
  const bool on = !has_value || value != 0;
  if (what == "overcurrent") m.inject_overcurrent();
  else if (what == "overtemperature") m.set_temperature_offset(has_value ? value : 60.0);
  else if (what == "following-error") m.set_jam_force(has_value ? value : 20000.0);
  else if (what == "encoder-loss") m.set_encoder_lost(on);
  else if (what == "lost-frames") d->drop_frames(has_value ? static_cast<unsigned>(value < 0 ? 0 : value) : 10u);
  else if (what == "refuse-sdo") m.set_refuse_writes(on);
  else if (what == "dead") d->set_dead(on);
  else if (what == "probe") m.plant().set_probe_override(on);
  else if (what == "clear") {
    m.clear_injections();
    m.plant().set_probe_override(false);
    d->drop_frames(0);
    d->set_dead(false);
  } else {
    return "unknown injection \"" + words[2] + "\"; " + usage();
  }
  return "";
}

}  // namespace cnc::cia402::sim
