// A simulated EtherCAT slave controller (ESC): the register subset of the
// reference (identity, station address, DL status, AL control/status/code
// with the state machine, SII EEPROM interface, SMs incl. mailbox hand-over,
// FMMUs, DC with a drifting local clock and its drift loop, process RAM, the
// process-data watchdog) and the hooks an application (sim/coe_drive.hpp)
// fills in. Datagrams are executed by the segment (segment.hpp) in line
// order. No allocation on the process-data path.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "fieldbus/ethercat/frame.hpp"
#include "fieldbus/ethercat/protocol.hpp"

namespace cnc::ethercat::sim {

class Esc;

// The slave's firmware behind the ESC.
class SlaveApplication {
 public:
  virtual ~SlaveApplication() = default;
  // A complete mailbox write in SM0 (header included). Replies go through
  // esc.post_mailbox().
  virtual void on_mailbox(const uint8_t* data, std::size_t size, Esc& esc, int64_t now_ns) = 0;
  // An AL state change request the ESC found valid: 0 accepts, else the
  // AL status code of the refusal.
  virtual uint16_t check_transition(AlState from, AlState to, const Esc& esc) = 0;
  virtual void on_state(AlState from, AlState to, int64_t now_ns) = 0;
  // SM2 buffer complete (outputs) / SM3 about to be read (inputs).
  virtual void on_outputs(const uint8_t* data, std::size_t size, int64_t now_ns) noexcept = 0;
  virtual void fill_inputs(uint8_t* data, std::size_t size) noexcept = 0;
  // The process-data watchdog expired (outputs stopped).
  virtual void on_watchdog(int64_t now_ns) noexcept = 0;
  virtual void poll(int64_t now_ns) noexcept = 0;
  // A SYNC0 pulse at true time `t_ns` (DC cyclic operation active).
  virtual void on_sync0(int64_t t_ns) noexcept { (void)t_ns; }
};

struct EscConfig {
  std::string name = "slave";
  std::vector<uint8_t> sii;          // EEPROM image (sii_builder.hpp)
  uint16_t mailbox_out_start = 0x1000, mailbox_out_size = 128;
  uint16_t mailbox_in_start = 0x1080, mailbox_in_size = 128;
  bool dc = true;
  double drift_ppm = 0;              // local clock rate error
  int64_t clock_at_power_on_ns = 0;  // local clock value at power-on
  int64_t forward_delay_ns = 750;    // processing + cable, per hop
};

class Esc {
 public:
  static constexpr std::size_t kMemory = 0x2000;  // registers + 4 KiB process RAM
  static constexpr unsigned kSms = 8, kFmmus = 8;

  Esc(EscConfig config, SlaveApplication* app, int64_t now_ns);

  const std::string& name() const noexcept { return cfg_.name; }
  const EscConfig& config() const noexcept { return cfg_; }

  // Executes one datagram addressed to this slave (the segment decides
  // which); returns the working-counter increment. `t_fwd`/`t_ret` are the
  // true times the frame passes port 0 and comes back on port 1.
  // `readers_before` is used by ARMW/FRMW.
  uint16_t execute(DatagramRef& d, bool addressed_read_only, int64_t t_fwd_ns, int64_t t_ret_ns,
                   bool port1_open) noexcept;
  // Logical addressing through the FMMUs: the WKC increment.
  uint16_t execute_logical(DatagramRef& d, int64_t now_ns) noexcept;
  // Watchdog and application time.
  void poll(int64_t now_ns) noexcept;

  uint16_t station_address() const noexcept { return get16(mem_.data() + reg::kStationAddress); }
  uint16_t alias() const noexcept { return get16(mem_.data() + reg::kStationAlias); }
  bool alias_enabled() const noexcept { return (mem_[reg::kDlControl + 3] & 0x01) != 0; }
  AlState state() const noexcept { return state_; }
  uint16_t al_status_code() const noexcept { return get16(mem_.data() + reg::kAlStatusCode); }
  bool error_indicated() const noexcept { return error_; }
  SmEntry sm(unsigned n) const noexcept { return SmEntry::decode(mem_.data() + reg::kSm0 + 8 * n); }
  FmmuEntry fmmu(unsigned n) const noexcept { return FmmuEntry::decode(mem_.data() + reg::kFmmu0 + 16 * n); }
  bool sync0_active() const noexcept { return (mem_[reg::kDcActivation] & 0x03) == 0x03; }
  uint32_t sync0_cycle_ns() const noexcept { return get32(mem_.data() + reg::kDcSync0Cycle); }
  bool outputs_valid() const noexcept { return outputs_valid_; }
  // The process-data watchdog as the master configured it: its time
  // (0x0400/0x0420) and whether SM2 triggers it (control bit 6).
  int64_t watchdog_time_ns() const noexcept { return watchdog_ns(); }
  bool watchdog_enabled() const noexcept { return (sm(2).control & sm::kWatchdogTrigger) && watchdog_ns() > 0; }

  // Mailbox towards the master (SM1), queued while SM1 is full (up to 8
  // messages of 256 bytes; more are dropped and counted). No allocation.
  void post_mailbox(const uint8_t* data, std::size_t size) noexcept;
  uint64_t mailbox_overflows() const noexcept { return mailbox_overflows_; }
  // An error the application detected: drop to `to` with the code.
  void set_error(AlState to, uint16_t code, int64_t now_ns) noexcept;

  // DC: the local clock and the system time at true time t.
  int64_t local_time(int64_t t_ns) const noexcept;
  int64_t system_time(int64_t t_ns) const noexcept;
  int64_t system_time_difference() const noexcept { return last_diff_ns_; }

  // Fault injection: `n` corrupted frames received at `port` (0..3), as
  // the error counters 0x0300-0x0313 count them (8 bits, stop at 255).
  void inject_invalid_frames(unsigned port, unsigned n) noexcept;
  void inject_lost_link(unsigned port) noexcept;
  // Fault injection: refuse the transition into `s` with `code` (0: accept).
  void refuse_state(AlState s, uint16_t code) noexcept { refuse_state_ = s, refuse_code_ = code; }
  uint64_t watchdog_expiries() const noexcept { return wd_expired_; }
  uint64_t sync0_pulses() const noexcept { return sync0_pulses_; }
  uint64_t outputs_received() const noexcept { return outputs_count_; }

 private:
  bool read(uint16_t addr, uint16_t len, uint8_t* out, bool or_mode, int64_t t) noexcept;
  bool write(uint16_t addr, uint16_t len, const uint8_t* in, int64_t t_fwd, int64_t t_ret, bool port1) noexcept;
  void after_write(uint16_t addr, uint16_t len, int64_t t_fwd, int64_t t_ret, bool port1) noexcept;
  void al_request(uint8_t value, int64_t now) noexcept;
  void enter(AlState s, int64_t now) noexcept;
  void sii_command() noexcept;
  void set_al_status() noexcept;
  void drift_control(uint64_t received, unsigned bytes, int64_t t) noexcept;
  void rate_anchor(int64_t t) noexcept;
  void refill_mailbox() noexcept;
  int64_t watchdog_ns() const noexcept;
  static bool overlaps(uint16_t a, uint16_t len, uint16_t r, uint16_t rlen) noexcept {
    return a < r + rlen && r < a + len;
  }

  EscConfig cfg_;
  SlaveApplication* app_;
  std::array<uint8_t, kMemory> mem_{};
  AlState state_ = AlState::Init;
  bool error_ = false;
  bool port1_open_ = true;
  // mailbox
  bool sm1_full_ = false;
  // Replies waiting for SM1 (fixed ring: posting never allocates).
  struct Pending {
    std::array<uint8_t, 256> data{};
    std::size_t size = 0;
  };
  std::array<Pending, 8> mailbox_queue_{};
  std::size_t mq_head_ = 0, mq_count_ = 0;
  uint64_t mailbox_overflows_ = 0;
  // process data
  bool outputs_valid_ = false;
  int64_t last_outputs_ns_ = 0;
  uint64_t outputs_count_ = 0, wd_expired_ = 0;
  // DC
  void run_sync0(int64_t now_ns) noexcept;
  int64_t sync0_next_ = -1;  // system time of the next SYNC0 pulse; -1: inactive
  uint64_t sync0_pulses_ = 0;
  int64_t anchor_t_ = 0, anchor_local_ = 0;
  double correction_ = 0;  // rate correction of the drift loop
  int64_t last_diff_ns_ = 0;
  // injection
  AlState refuse_state_ = AlState::None;
  uint16_t refuse_code_ = 0;
};

}  // namespace cnc::ethercat::sim
