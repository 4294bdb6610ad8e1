// A simulated EtherCAT segment: slaves in a line behind one master port.
// A frame passes every connected slave in order (auto-increment and
// broadcast addresses counted per slave, FMMU matching for logical
// commands) and comes back with the working counters set. Faults can be
// injected: lost frames, wrong working counters, a cable break after a
// slave. Used in-process (sim_link: "sim:<name>") and by the ecat-sim
// program on a real or veth interface. Simulation only (sim/).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "fieldbus/ethercat/link.hpp"
#include "sim/ethercat/coe_drive.hpp"
#include "sim/ethercat/esc.hpp"

namespace cnc::ethercat::sim {

class Segment {
 public:
  // `clock` gives the true time in ns (default CLOCK_MONOTONIC).
  explicit Segment(std::function<int64_t()> clock = {});

  // Adds a slave at the end of the line (the application outlives it).
  Esc& add(EscConfig config, SlaveApplication* app);
  // Adds `n` simulated CiA 402 drives (names "drive-1".., clocks drifting
  // by a few ppm each, the first one the reference).
  void add_drives(unsigned n, const CoeDriveConfig& base = {});

  std::size_t size() const noexcept { return slaves_.size(); }
  Esc& slave(std::size_t i) noexcept { return *slaves_[i]; }
  CoeDrive* drive(std::size_t i) noexcept { return i < drives_.size() ? drives_[i].get() : nullptr; }
  int64_t now() const { return clock_(); }

  // Runs a frame through the line in place; false when the frame is lost
  // (injected) or not an EtherCAT frame. Thread-safe (one frame at a time).
  bool process(uint8_t* frame, std::size_t size);
  // Time passes without frames (watchdogs, drives coasting).
  void poll();
  // The slaves' own clock thread (one thread only): poll(), unless frames
  // reached every slave since the previous call (each frame polls the
  // slaves it passes). So while a master exchanges frames the clock thread
  // never holds the segment's lock that the master's servo thread takes to
  // send. Returns whether it polled.
  bool poll_if_idle();

  // --- fault injection ---
  void drop_frames(unsigned n) noexcept { drop_.store(n); }
  // The next `n` frames with a logical datagram get `delta` added to its WKC.
  void corrupt_wkc(unsigned n, int delta) noexcept { wkc_delta_ = delta, corrupt_.store(n); }
  // Cable break after slave `position` (1-based; 0 = none): later slaves are unreachable.
  void break_after(unsigned position) noexcept { break_after_.store(position); }
  uint64_t frames() const noexcept { return frames_.load(); }
  uint64_t frames_dropped() const noexcept { return dropped_.load(); }

  std::mutex& mutex() noexcept { return mutex_; }

 private:
  void execute(DatagramRef& d, std::size_t connected, int64_t t) noexcept;

  std::function<int64_t()> clock_;
  std::vector<std::unique_ptr<CoeDrive>> drives_;
  std::vector<std::unique_ptr<Esc>> slaves_;
  std::mutex mutex_;
  std::atomic<unsigned> drop_{0}, corrupt_{0}, break_after_{0};
  int wkc_delta_ = 0;
  std::atomic<uint64_t> frames_{0}, dropped_{0};
  uint64_t passed_at_idle_poll_ = 0;  // frames that passed every slave, at the last poll_if_idle()
};

// Named segments for in-process links ("sim:<name>"): registering one also
// registers the link kind "sim" with ethercat::open_link.
void register_sim_link_kind();
void register_segment(const std::string& name, std::shared_ptr<Segment> segment);
void unregister_segment(const std::string& name);
std::shared_ptr<Segment> find_segment(const std::string& name);
// A link that delivers frames to the segment and returns the replies.
std::unique_ptr<Link> open_sim_link(std::shared_ptr<Segment> segment, const std::string& name);

}  // namespace cnc::ethercat::sim
