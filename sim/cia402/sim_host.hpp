// Runs simulated CiA 402 drives on one CAN transport: several drives per
// host (one process, or inside the controller for the simulated mill), in
// a thread of its own or stepped by hand (tests with a manual bus clock).
// Fault injection arrives as text commands (the `cnc inject` CLI, a test,
// or the simulator program's standard input) and is applied between passes.
//
//   drive <node> overcurrent                 fault 0x2310 (power stage off at once)
//   drive <node> overtemperature [kelvin]    heats the drive by <kelvin> (60): warning, then fault 0x4210
//   drive <node> following-error [newton]    jams the table (20000 N): the drive's window trips, 0x8611
//   drive <node> encoder-loss [1|0]          fault 0x7305 while lost
//   drive <node> lost-frames [count]         the next <count> (10) SYNC/RPDO frames never arrive
//   drive <node> refuse-sdo [1|0]            parameter writes are refused (abort 0x08000022)
//   drive <node> dead [1|0]                  the drive stops answering (power cut)
//   drive <node> probe [1|0]                 the touch probe input
//   drive <node> clear                       every injection off
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "sim/cia402/canopen_drive.hpp"
#include "core/util/fixed_string.hpp"
#include "core/util/spsc_ring.hpp"
#include "fieldbus/can/transport.hpp"

namespace cnc::cia402::sim {

class SimHost {
 public:
  explicit SimHost(can::Transport& transport) : transport_(transport) {}
  ~SimHost() { stop(); }
  SimHost(const SimHost&) = delete;
  SimHost& operator=(const SimHost&) = delete;

  // Before start(). The host owns its drives. A drive given a transport of
  // its own is a controller of its own on the bus (frames of several drives
  // then meet in the bus's arbitration, by identifier, as separate devices'
  // do; on the host's one transport they queue behind each other in order).
  CanopenDrive& add(const SimNodeConfig& config, std::unique_ptr<can::Transport> own = nullptr);
  std::size_t size() const noexcept { return drives_.size(); }
  CanopenDrive& at(std::size_t i) noexcept { return *drives_[i]; }
  CanopenDrive* find(uint8_t node) noexcept;

  // Powers the drives on and starts the thread.
  void start();
  void stop();
  bool running() const noexcept { return thread_.joinable(); }
  // Without the thread: power on at `now_ns`, then one pass per call.
  void power_on(int64_t now_ns);
  void step(int64_t now_ns);

  // Applies an injection command (see above); "" when done, else why not.
  // From any one non-realtime thread: when something else steps the host
  // (its thread, or the servo thread) the command waits for the next pass.
  std::string inject(const std::string& command, double value, bool has_value);
  // Someone other than the caller of inject() steps the host (set it before
  // that starts; start() sets it).
  void set_stepped_elsewhere(bool on) noexcept { stepped_elsewhere_.store(on, std::memory_order_release); }
  // Passes run so far (each: frames delivered, drives polled).
  uint64_t passes() const noexcept { return passes_.load(std::memory_order_relaxed); }
  // Called at the end of every pass, in the host's thread (HAL pins).
  std::function<void()> after_pass;

 private:
  struct Injection {
    FixedString<96> text;
    double value = 0;
    bool has_value = false;
    uint32_t serial = 0;
  };
  struct Outcome {
    uint32_t serial = 0;
    FixedString<200> why;
  };
  // Allocation-free: it may run in the servo thread.
  void apply(const Injection& in, FixedString<200>& why) noexcept;

  // Frame times further than this from the pass's clock are not believed.
  static constexpr int64_t kTrustedAgeNs = 10'000'000'000;

  // Frames of one transport to its drives (all on the host's transport, or
  // the one drive that owns it).
  void deliver(can::Transport& from, int64_t& last_frame_ns, CanopenDrive* only, int64_t now_ns) noexcept;

  can::Transport& transport_;
  std::vector<std::unique_ptr<CanopenDrive>> drives_;
  std::vector<std::unique_ptr<can::Transport>> own_;  // per drive, or null: the host's
  std::vector<int64_t> own_last_frame_ns_;
  bool any_shared_ = false;
  int64_t last_frame_ns_ = 0;  // reception time of the last frame delivered from transport_
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> stepped_elsewhere_{false};
  std::atomic<uint64_t> passes_{0};
  std::mutex inject_mutex_;  // one injecting client at a time (never taken by a pass)
  uint32_t serial_ = 0;
  SpscRing<Injection, 8> requests_;
  SpscRing<Outcome, 8> outcomes_;
};

}  // namespace cnc::cia402::sim
