// The scope: samples up to kMaxChannels HAL pins every cycle of the thread
// its function `scope.sample` runs in, into a buffer sized at `loadrt
// scope samples=N` (no allocation in the servo thread), with a trigger on
// one of the channels, a pre-trigger share and the modes single, normal
// and auto of LinuxCNC's halscope. The servo thread is the single
// producer; the non-realtime side (halcmd's `scope` command, hence
// `cnc-scope`) configures, arms and reads a capture only while the
// producer does not write it (the state word says who owns the buffer).
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "core/hal/component.hpp"

namespace cnc::hal {

enum class ScopeEdge : uint8_t { Rising, Falling, Level, None };  // None: trigger at once
enum class ScopeMode : uint8_t { Single, Normal, Auto };

// The buffer and its trigger, apart from the HAL so it can be tested alone.
class ScopeCapture {
 public:
  static constexpr int kMaxChannels = 16;
  enum class State : uint8_t { Idle, Filling, Waiting, Post, Done };

  ScopeCapture(std::size_t capacity, int channels);

  // Non-realtime, while not running (Idle or Done): the capture's shape.
  // `samples` <= capacity; `pre_percent` 0..100 of them before the trigger;
  // the trigger channel's value compared with `level`. Auto: triggers by
  // itself when no trigger came within `samples` cycles of waiting.
  void configure(int channels, std::size_t samples, int pre_percent, int trigger_channel, ScopeEdge edge,
                 double level, ScopeMode mode);
  void arm() noexcept;   // starts a capture (Idle/Done -> Filling)
  void stop() noexcept;  // -> Idle

  // Realtime: one sample of every channel (values as doubles).
  void push(const double* values) noexcept;

  State state() const noexcept { return state_.load(std::memory_order_acquire); }
  bool forced() const noexcept { return forced_.load(std::memory_order_relaxed); }  // Auto fired without a trigger
  // Non-realtime, when Done: the captured rows in time order (the trigger
  // row is `pre` rows in).
  std::vector<std::vector<double>> rows() const;
  std::size_t pre_samples() const noexcept { return pre_; }
  std::size_t samples() const noexcept { return samples_; }
  int channels() const noexcept { return channels_; }
  ScopeMode mode() const noexcept { return mode_; }

 private:
  std::vector<double> buffer_;  // capacity x kMaxChannels, allocated once
  std::size_t capacity_;
  int channels_ = 1;
  std::size_t samples_ = 0, pre_ = 0;
  int trigger_channel_ = 0;
  ScopeEdge edge_ = ScopeEdge::None;
  double level_ = 0;
  ScopeMode mode_ = ScopeMode::Single;
  // Producer's counters; read by the consumer only after Done (acquire).
  std::size_t written_ = 0;       // samples written since arm
  std::size_t trigger_at_ = 0;    // index (since arm) of the trigger sample
  std::size_t waited_ = 0;
  double previous_ = 0;
  std::atomic<bool> forced_{false};
  std::atomic<State> state_{State::Idle};
};

// `loadrt scope [samples=N]` (default 4000, up to 1000000): function
// `scope.sample`, added last to the servo thread. Driven by halcmd:
//   scope setup PIN[,PIN...] [trigger=PIN] [edge=rising|falling|level|none]
//               [level=V] [pre=PERCENT] [samples=N] [mode=single|normal|auto]
//   scope arm | scope stop | scope state | scope csv
class Scope : public Component {
 public:
  Scope(ComponentContext& ctx, const LoadArgs& args);
  // One halcmd `scope ...` line's words after "scope"; returns the output.
  std::string command(const std::vector<std::string>& words);
  void sample(const rt::CycleInfo& info) noexcept;

 private:
  std::string csv();
  ScopeCapture capture_;
  std::vector<std::string> names_;
  // Read by the servo thread only while the capture runs; changed only
  // while it does not.
  const detail::PinObj* pins_[ScopeCapture::kMaxChannels] = {};
  Type types_[ScopeCapture::kMaxChannels] = {};
  std::atomic<int> active_{0};
  std::atomic<uint64_t> first_cycle_{0};
  std::atomic<int64_t> period_ns_{0};  // written by the servo thread, read by csv
};

}  // namespace cnc::hal
