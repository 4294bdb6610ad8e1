#include "fieldbus/canopen/slave_runner.hpp"

namespace cnc::canopen {

void SlaveRunner::start() {
  if (thread_.joinable()) return;
  const int64_t now = transport_.now_ns();
  for (SlaveNode* n : nodes_) n->start(now);
  stop_.store(false);
  thread_ = std::thread([this] {
    while (!stop_.load(std::memory_order_acquire)) {
      transport_.wait(1'000'000);
      step(transport_.now_ns());
    }
  });
}

void SlaveRunner::stop() {
  if (!thread_.joinable()) return;
  stop_.store(true);
  thread_.join();
}

void SlaveRunner::call(std::function<void()> f) {
  if (!thread_.joinable()) {
    f();
    return;
  }
  std::lock_guard<std::mutex> lock(calls_mutex_);
  calls_.push_back(std::move(f));
}

void SlaveRunner::step(int64_t now_ns) {
  std::vector<std::function<void()>> calls;
  {
    std::lock_guard<std::mutex> lock(calls_mutex_);
    calls.swap(calls_);
  }
  for (auto& f : calls) f();
  can::Frame f;
  while (transport_.receive(f)) {
    for (SlaveNode* n : nodes_) n->on_frame(f, now_ns);
  }
  for (SlaveNode* n : nodes_) n->poll(now_ns);
}

}  // namespace cnc::canopen
