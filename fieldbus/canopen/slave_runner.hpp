// Runs simulated CANopen devices (SlaveNode) on one transport in a thread
// of their own: frames go to every device, timers are polled at least once
// a millisecond. For the simulated machine (virtual bus) and the device
// programs of the VM tests (SocketCAN). Non-realtime.
#pragma once

#include <atomic>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include "fieldbus/can/transport.hpp"
#include "fieldbus/canopen/slave_node.hpp"

namespace cnc::canopen {

class SlaveRunner {
 public:
  explicit SlaveRunner(can::Transport& transport) : transport_(transport) {}
  ~SlaveRunner() { stop(); }
  SlaveRunner(const SlaveRunner&) = delete;
  SlaveRunner& operator=(const SlaveRunner&) = delete;

  // Before start(); the runner does not own the nodes.
  void add(SlaveNode& node) { nodes_.push_back(&node); }
  // Powers the devices on (boot-up messages) and starts the thread.
  void start();
  void stop();
  bool running() const noexcept { return thread_.joinable(); }
  // One pass without the thread: deliver waiting frames, poll timers.
  void step(int64_t now_ns);
  // Runs `f` in the runner's thread between passes (to touch a device safely).
  void call(std::function<void()> f);

 private:
  can::Transport& transport_;
  std::vector<SlaveNode*> nodes_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::mutex calls_mutex_;
  std::vector<std::function<void()>> calls_;
};

}  // namespace cnc::canopen
