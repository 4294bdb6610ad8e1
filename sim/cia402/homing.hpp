// The homing methods of a simulated drive (CiA 402 homing mode): a short
// plan of moves built from the method (which switch, which of its edges,
// from which side, with or without the zero pulse), run against the
// plant's switches and index at the fine time step. Supported: 1-6
// (limit or home switch, then index), 17-22 (the same at the switch edge),
// 33/34 (index only), 35/37 (current position). Edges are always crossed
// at the zero-search speed in the final direction, after a fast search at
// the switch-search speed, so the reference does not depend on the speed.
#pragma once

#include <array>
#include <cstdint>

namespace cnc::cia402::sim {

class HomingEngine {
 public:
  enum class Status : uint8_t { Idle, InProgress, Attained, Completed, Error };

  struct Inputs {
    bool neg_limit = false, pos_limit = false, home = false;
    bool index = false;          // a zero pulse passed in this step
    double index_counts = 0;     // where (exact encoder counts)
    double counts = 0;           // encoder counts now (exact)
    double velocity = 0;         // counts/s now (measured)
  };
  struct Output {
    double velocity = 0;         // reference, counts/s
    double acceleration = 0;     // reference, counts/s^2
    bool home_event = false;     // the reference was found in this step
    double home_counts = 0;      // exact encoder counts of the reference
  };

  static bool is_supported(int method) noexcept;

  // False (and Error) for a method this drive does not support.
  bool start(int method, double switch_speed, double zero_speed, double accel, const Inputs& now) noexcept;
  void interrupt() noexcept;  // halt or start bit cleared: stop, not homed
  Output step(double dt, const Inputs& in) noexcept;
  Status status() const noexcept { return status_; }
  bool is_moving() const noexcept { return v_ != 0.0; }
  const char* error() const noexcept { return error_; }

 private:
  enum class Sensor : uint8_t { None, NegLimit, PosLimit, Home };
  enum class Until : uint8_t { On, Off, Index, Now };
  struct Move {
    int dir = 0;
    bool fast = false;
    Until until = Until::Now;
    bool reference = false;  // the condition is the reference point
    bool stop = true;        // come to rest before the next move
  };
  bool sensor(const Inputs& in) const noexcept;
  void add(Move m) noexcept { if (count_ < plan_.size()) plan_[count_++] = m; }
  void fail(const char* why) noexcept;

  Status status_ = Status::Idle;
  Sensor sensor_ = Sensor::None;
  std::array<Move, 8> plan_{};
  std::size_t count_ = 0, at_ = 0;
  bool stopping_ = false;
  bool done_after_stop_ = false;
  double v_ = 0;              // reference velocity, counts/s
  double target_v_ = 0;
  double switch_speed_ = 0, zero_speed_ = 0, accel_ = 0;
  const char* error_ = "";
};

}  // namespace cnc::cia402::sim
