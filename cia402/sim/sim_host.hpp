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

#include "cia402/sim/canopen_drive.hpp"
#include "fieldbus/can/transport.hpp"

namespace cnc::cia402::sim {

class SimHost {
 public:
  explicit SimHost(can::Transport& transport) : transport_(transport) {}
  ~SimHost() { stop(); }
  SimHost(const SimHost&) = delete;
  SimHost& operator=(const SimHost&) = delete;

  // Before start(). The host owns its drives.
  CanopenDrive& add(const SimNodeConfig& config);
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
  // Thread-safe: with the thread running it waits for the next pass.
  std::string inject(const std::string& command, double value, bool has_value);
  // Runs `f` in the host's thread between passes (or now without thread).
  void call(std::function<void()> f);
  // Passes run so far (each: frames delivered, drives polled).
  uint64_t passes() const noexcept { return passes_.load(std::memory_order_relaxed); }
  // Called at the end of every pass, in the host's thread (HAL pins).
  std::function<void()> after_pass;

 private:
  std::string apply(const std::string& command, double value, bool has_value);

  can::Transport& transport_;
  std::vector<std::unique_ptr<CanopenDrive>> drives_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> passes_{0};
  std::mutex calls_mutex_;
  std::vector<std::function<void()>> calls_;
};

}  // namespace cnc::cia402::sim
