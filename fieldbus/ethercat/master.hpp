// The EtherCAT master: bus scan (slave count, station addresses, SII),
// INIT -> PREOP -> SAFEOP -> OP with AL status codes decoded, SM and FMMU
// configuration, PDO assignment and mapping and start-up SDOs over CoE,
// distributed clocks (delays, offsets, static drift, SYNC0) and the cyclic
// exchange. The cyclic part (cyclic_read / cyclic_write) runs in the servo
// thread: one frame per cycle (LRW of all process data, FRMW of the
// reference clock, BRD of the AL status), no allocation, no lock, no
// exception. Mailbox traffic and diagnosis run on the master's own worker
// thread with its own link, never in the servo thread. Any start-up failure
// throws StartupError naming the slave, the object and the reason.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "core/util/process_slot.hpp"
#include "fieldbus/ethercat/dc.hpp"
#include "fieldbus/ethercat/frame.hpp"
#include "fieldbus/ethercat/link.hpp"
#include "fieldbus/ethercat/sii.hpp"

namespace cnc {
class MessageQueue;
}

namespace cnc::ethercat {

struct PdoEntryConfig {
  uint16_t index = 0;
  uint8_t sub = 0;
  uint8_t bits = 0;
  uint32_t encode() const noexcept { return (uint32_t{index} << 16) | (uint32_t{sub} << 8) | bits; }
};

struct StartupSdo {
  uint16_t index = 0;
  uint8_t sub = 0;
  std::vector<uint8_t> data;
  std::string origin;  // "machine.ini:42" for messages
};

struct SlaveConfig {
  unsigned position = 0;  // 1-based ring position
  std::string name;
  std::optional<uint32_t> vendor_id, product_code, revision;
  // Process data; empty optional: the SII defaults.
  std::optional<std::vector<PdoEntryConfig>> rx_pdo, tx_pdo;
  uint16_t rx_pdo_index = 0x1600, tx_pdo_index = 0x1A00;
  std::vector<StartupSdo> sdos;
  bool sync0 = true;        // DC SYNC0 when the bus uses DC
  uint32_t watchdog_ms = 100;  // process-data (SM2) watchdog; 0: off (see MasterConfig::watchdog_ms)
  std::string esi;          // ESI XML file: PDO defaults and AssignActivate from it
  bool complete_access = false;  // PDO assignment and mapping in one transfer each (when the SII allows it)
};

struct MasterConfig {
  std::string name = "ethercat.0";      // HAL prefix and message source
  std::string interface;                // raw:<if> or sim:<segment>
  int64_t cycle_ns = 1'000'000;
  std::vector<SlaveConfig> slaves;      // empty: every slave found, SII defaults
  unsigned miss_limit = 3;              // consecutive bad cycles that stop the bus; 0 = never
  uint32_t watchdog_ms = 100;           // SM watchdog of slaves without a SlaveConfig; 0: off
  bool dc = true;
  bool dc_lock = true;                  // servo thread follows the reference clock
  int64_t sync0_shift_ns = -1;          // SYNC0 this far into the DC cycle; -1: half a cycle
  unsigned dc_static_drift_frames = 500;
  int64_t state_timeout_ms = 3000;
  int64_t mailbox_timeout_ms = 1000;
  unsigned op_after_good_cycles = 20;   // SAFEOP -> OP once this many cycles were good
  // Benchmarks only: cyclic_write waits (spinning) this long for the reply
  // to measure the frame round trip; 0 in a controller.
  int64_t spin_for_reply_ns = 0;
  const SlaveConfig* slave(unsigned position) const noexcept {
    for (const auto& s : slaves) {
      if (s.position == position) return &s;
    }
    return nullptr;
  }
};

class StartupError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct SdoResult {
  bool ok = false;
  uint32_t abort_code = 0;
  std::vector<uint8_t> data;
  std::string error;  // "aborted by the slave: 0x06040041 object cannot be mapped to the PDO", "no answer within 1000 ms"
};

// SDO information (CoE service 8) about one object or entry.
struct SdoInfoObject {
  uint16_t index = 0, data_type = 0;
  uint8_t max_sub = 0, object_code = 0;  // 7 VAR, 8 ARRAY, 9 RECORD
  std::string name;
};
struct SdoInfoEntry {
  uint16_t index = 0, data_type = 0, bit_length = 0, access = 0;
  uint8_t sub = 0;
  std::string name;
};

// What the scan found about one slave.
struct SlaveInfo {
  unsigned position = 0;  // 1-based
  uint16_t station = 0;
  std::string name;       // configured name, else the SII name
  SiiInfo sii;
  bool has_dc = false;
  bool port1_open = false;
  uint16_t features = 0;
  std::vector<PdoEntryConfig> rx, tx;  // the mapping in use
  uint32_t out_bit = 0, out_bits = 0, in_bit = 0, in_bits = 0;  // in the output / input image
  uint16_t sm2_start = 0, sm3_start = 0;
  int64_t dc_delay_ns = 0, dc_offset_ns = 0;
  uint16_t assign_activate = 0x0300;  // written to 0x0980 (from the ESI when given); 0: no SYNC0
  std::string esi_device;             // "SIM402 (file.xml:12)" when an ESI file described it
};

enum class BusPhase : uint8_t { Down, SafeOp, Op, Fault };

// A slave controller's error counters, registers 0x0300-0x0313 (each an
// 8-bit counter that stops at 255; any write clears them): per port the
// invalid frames (CRC or framing) and physical-layer RX errors it
// received, the frames that arrived already marked bad by a slave before
// it (forwarded RX errors) and the link losses; the processing unit's and
// the PDI's errors. A corrupted frame shows here at the port it entered,
// while the master only sees a lost frame or a wrong working counter.
struct EscErrorCounters {
  static constexpr uint16_t kBytes = 0x14;
  std::array<uint8_t, 4> invalid_frames{}, rx_errors{}, forwarded{}, lost_links{};
  uint8_t processing_unit = 0, pdi = 0;
  bool read = false;  // false until the first read answered

  static EscErrorCounters decode(const uint8_t* r) noexcept;
  bool any() const noexcept;
  // "port 0: 3 invalid frames, 1 RX error; port 1: 1 lost link", only what
  // is not 0 ("" when nothing is).
  std::string text() const;
  // What grew from `before` to this, in the same words.
  std::string growth_since(const EscErrorCounters& before) const;
};

// Counters of the cyclic exchange (servo thread writes, anyone reads).
// Frame round-trip times, 1 us bins up to 10 ms (benchmarks; no allocation).
struct RoundTripHistogram {
  static constexpr std::size_t kBins = 10'000;
  std::array<uint32_t, kBins + 1> bins{};
  uint64_t count = 0;
  void add(int64_t ns) noexcept {
    const auto b = static_cast<std::size_t>(std::clamp<int64_t>(ns / 1000, 0, kBins));
    ++bins[b];
    ++count;
  }
  // Upper edge of the bin holding quantile q (0..1), ns.
  int64_t quantile_ns(double q) const noexcept {
    if (count == 0) return 0;
    const auto want = static_cast<uint64_t>(q * static_cast<double>(count - 1)) + 1;
    uint64_t seen = 0;
    for (std::size_t i = 0; i <= kBins; ++i) {
      seen += bins[i];
      if (seen >= want) return static_cast<int64_t>(i + 1) * 1000;
    }
    return static_cast<int64_t>(kBins) * 1000;
  }
};

struct CyclicCounters {
  std::atomic<uint64_t> cycles{0}, frames_sent{0}, send_errors{0}, frames_lost{0}, frames_late{0}, wkc_errors{0};
  std::atomic<uint32_t> consecutive_bad{0};
  std::atomic<uint16_t> last_wkc{0};
  std::atomic<uint16_t> al_status_or{0};
  std::atomic<uint32_t> dc_sync_diff_ns{0};
  std::atomic<bool> inputs_fresh{false};
};

class Master {
 public:
  Master(MasterConfig config, MessageQueue* messages);
  // With links given (tests): the cyclic one for the servo thread, the
  // acyclic one for start-up and the worker.
  Master(MasterConfig config, MessageQueue* messages, std::unique_ptr<Link> cyclic, std::unique_ptr<Link> acyclic);
  ~Master();
  Master(const Master&) = delete;
  Master& operator=(const Master&) = delete;

  const std::string& name() const noexcept { return cfg_.name; }
  const MasterConfig& config() const noexcept { return cfg_; }
  // The bus cycle, once the thread that runs the bus is known (before
  // start_up); re-checks what depends on it (SYNC0 shift, watchdogs).
  // Throws std::runtime_error.
  void set_cycle_ns(int64_t ns);

  // --- start-up (non-realtime) ---
  // Scan only: count, station addresses, SII; compares with the
  // configuration. Throws StartupError.
  void scan();
  // The process image from the configured or SII-default PDOs (scans
  // first if needed): slots are valid from here on.
  void plan();
  // Scan (if needed) and every slave to PREOP with its mailbox: enough for
  // SDOs and SDO information (tools). Throws StartupError.
  void to_preop();
  // plan() + PREOP + CoE configuration + SM/FMMU + DC + SAFEOP; the bus is
  // ready for cyclic exchange. Throws StartupError.
  void start_up();
  // The worker thread: mailbox requests, SAFEOP -> OP once the cyclic
  // exchange is good, emergencies, diagnosis and messages.
  void start_worker();
  // Stops the worker (queued requests are still answered).
  void stop();
  // stop() and every slave back to INIT (controller shutdown).
  void release();

  // After a safe stop (cable mended, slave powered again): the worker
  // scans and brings the bus up again; the slaves must be the same as
  // before (the drives hold slots into the image). Realtime-safe request.
  void request_restart() noexcept { restart_requested_.store(true, std::memory_order_relaxed); }

  // --- servo thread ---
  void cyclic_read(int64_t now_ns) noexcept;
  void cyclic_write(int64_t now_ns) noexcept;
  // The wake-up shift the DC lock asks for (taken once).
  int64_t take_phase_adjust() noexcept { return phase_adjust_.exchange(0, std::memory_order_relaxed); }

  // --- process image (slots valid after start_up) ---
  ProcessSlot output(unsigned position, uint16_t index, uint8_t sub) const noexcept;
  ProcessSlot input(unsigned position, uint16_t index, uint8_t sub) const noexcept;
  uint32_t output_bytes() const noexcept { return static_cast<uint32_t>(outputs_.size()); }
  uint32_t input_bytes() const noexcept { return static_cast<uint32_t>(inputs_.size()); }
  uint16_t expected_wkc() const noexcept { return expected_wkc_; }

  // --- mailbox (non-realtime, any thread; through the worker once it runs) ---
  // With `complete_access` (sub 0 or 1) every sub-index at once, sub-index
  // 0 taking 16 bits (CoE complete access).
  SdoResult sdo_upload(unsigned position, uint16_t index, uint8_t sub, bool complete_access = false);
  SdoResult sdo_download(unsigned position, uint16_t index, uint8_t sub, const std::vector<uint8_t>& data,
                         bool complete_access = false);
  // SDO information: the slave's object list and descriptions. `error` is
  // set (and the result empty) when the slave refuses or does not answer.
  std::vector<uint16_t> sdo_info_list(unsigned position, std::string& error);
  std::optional<SdoInfoObject> sdo_info_object(unsigned position, uint16_t index, std::string& error);
  std::optional<SdoInfoEntry> sdo_info_entry(unsigned position, uint16_t index, uint8_t sub, std::string& error);
  // Realtime requests (expedited values), done by the worker: a handle or -1.
  int rt_sdo_read(unsigned position, uint16_t index, uint8_t sub) noexcept;
  int rt_sdo_write(unsigned position, uint16_t index, uint8_t sub, uint32_t value, uint8_t size) noexcept;
  bool rt_sdo_poll(int handle, uint32_t& abort_code, uint32_t& value) noexcept;

  // --- state ---
  BusPhase phase() const noexcept { return phase_.load(std::memory_order_acquire); }
  bool is_operational() const noexcept { return phase() == BusPhase::Op; }
  bool has_fault() const noexcept { return phase() == BusPhase::Fault; }
  std::string fault_text() const;
  const std::vector<SlaveInfo>& slaves() const noexcept { return slaves_; }
  std::size_t slave_count() const noexcept { return slaves_.size(); }
  uint8_t slave_al_state(unsigned position) const noexcept;
  uint16_t slave_al_code(unsigned position) const noexcept;
  uint16_t slave_emcy_code(unsigned position) const noexcept;
  uint32_t slave_emcy_count(unsigned position) const noexcept;
  // Port `port` (0-3) of a slave's error counters as last read (below):
  // invalid frames plus RX errors, and lost links. Servo-thread safe.
  uint16_t slave_port_rx_errors(unsigned position, unsigned port) const noexcept;
  uint8_t slave_port_lost_links(unsigned position, unsigned port) const noexcept;
  // The error counters of every slave (index position - 1) as last read:
  // cleared at start-up, read by the worker every second and at a fault.
  std::vector<EscErrorCounters> error_counters() const;
  // Reads them now (through the worker once it runs; not from the servo
  // thread), posts what grew since the last read and returns them.
  std::vector<EscErrorCounters> read_error_counters();
  const CyclicCounters& counters() const noexcept { return counters_; }
  const PhaseLock& phase_lock() const noexcept { return lock_; }
  void reset_lock_stats() noexcept { lock_.reset_stats(); }
  const RoundTripHistogram& round_trips() const noexcept { return rtt_; }
  bool uses_dc() const noexcept { return dc_ref_ >= 0; }
  // "slave 2 (y-axis)"
  std::string slave_label(unsigned position) const;

  // --- direct datagrams on the acyclic link (start-up, tools, tests) ---
  // Working counter, or nullopt when no reply came.
  std::optional<uint16_t> transact(Command c, uint32_t address, uint8_t* data, uint16_t length);

 private:
  struct RtRequest {
    std::atomic<int> state{0};  // 0 free, 1 requested, 2 done
    unsigned position = 0;
    uint16_t index = 0;
    uint8_t sub = 0, size = 0;
    bool write = false;
    uint32_t value = 0, abort_code = 0, result = 0;
  };
  struct SlaveState {
    std::atomic<uint8_t> al_state{0};
    std::atomic<uint16_t> al_code{0};
    std::atomic<uint16_t> emcy_code{0};
    std::atomic<uint32_t> emcy_count{0};
    // The ESC error counters as last read, per port, for the HAL pins.
    std::array<std::atomic<uint16_t>, 4> port_rx_errors{};  // invalid frames + RX errors
    std::array<std::atomic<uint8_t>, 4> port_lost_links{};
    uint8_t mailbox_counter = 0;
  };

  mutable std::mutex error_counters_mutex_;
  std::vector<EscErrorCounters> error_counters_;  // per slave, as last read

  [[noreturn]] void fail(const std::string& what) const;
  [[noreturn]] void fail_slave(const SlaveInfo& s, const std::string& what) const;
  uint16_t fprd(const SlaveInfo& s, uint16_t ado, uint8_t* data, uint16_t len);
  uint16_t fpwr(const SlaveInfo& s, uint16_t ado, const uint8_t* data, uint16_t len);
  void must_write(const SlaveInfo& s, uint16_t ado, const uint8_t* data, uint16_t len, const char* what);
  void clear_error_counters();
  // Reads the first `up_to` slaves' counters on this thread and posts what grew.
  void update_error_counters(std::size_t up_to = SIZE_MAX);
  std::vector<uint8_t> read_sii(const SlaveInfo& s);
  void request_state(SlaveInfo& s, AlState to);
  void configure_mailbox(SlaveInfo& s);
  void configure_coe(SlaveInfo& s);
  void layout_process_data();
  void configure_process_data(SlaveInfo& s);
  void configure_dc();
  void prepare_cyclic();
  static void drain(Link& link) noexcept;
  void spin_for_reply() noexcept;
  void check_sdo(SlaveInfo& s, uint16_t index, uint8_t sub, const std::vector<uint8_t>& data, const std::string& why,
                 bool complete_access = false);

  // mailbox on the acyclic link (worker or start-up thread)
  bool mailbox_write(SlaveInfo& s, const uint8_t* data, std::size_t size, std::string& error);
  bool mailbox_read(SlaveInfo& s, std::vector<uint8_t>& out, int64_t timeout_ns, std::string& error);
  bool coe_exchange(SlaveInfo& s, const uint8_t* sdo, std::size_t n, std::vector<uint8_t>& reply, std::string& error);
  SdoResult do_upload(SlaveInfo& s, uint16_t index, uint8_t sub, bool complete_access = false);
  // One SDO information request; the reply's data of all fragments.
  SdoResult do_info(SlaveInfo& s, uint8_t opcode, const std::vector<uint8_t>& request);
  SdoResult do_download(SlaveInfo& s, uint16_t index, uint8_t sub, const std::vector<uint8_t>& data,
                        bool complete_access = false);
  void handle_emergency(SlaveInfo& s, const uint8_t* data);
  SlaveInfo* find(unsigned position);
  SdoResult run_on_worker(std::function<SdoResult()> job);

  void worker_loop();
  // Runs the queued jobs until the queue is empty (the worker, and stop()
  // for requests queued while the worker stopped).
  void run_queued_jobs();
  void worker_go_op();
  void worker_poll_emergencies();
  void worker_report_fault();
  void worker_rt_requests();
  void worker_restart();
  void post(bool error, const std::string& text);

  MasterConfig cfg_;
  MessageQueue* messages_;
  std::unique_ptr<Link> cyclic_link_, acyclic_link_;
  std::vector<SlaveInfo> slaves_;
  std::unique_ptr<SlaveState[]> state_;
  uint8_t acyclic_index_ = 0x80;
  bool scanned_ = false, planned_ = false;

  // process image
  std::vector<uint8_t> outputs_, inputs_;
  uint16_t expected_wkc_ = 0;
  int dc_ref_ = -1;  // index into slaves_ of the reference clock

  // cyclic frame (servo thread)
  std::array<uint8_t, kMaxFrame> tx_{}, rx_{}, held_{};
  std::size_t tx_size_ = 0;
  std::size_t lrw_offset_ = 0, frmw_offset_ = 0, al_offset_ = 0, diff_offset_ = 0;
  uint8_t cyclic_index_ = 0;
  bool outstanding_ = false;
  std::size_t held_size_ = 0;  // a reply already taken by the spin (benchmarks)
  RoundTripHistogram rtt_;
  bool sent_in_op_ = false;  // the outstanding frame left while every slave was in OP
  CyclicCounters counters_;
  PhaseLock lock_;
  std::atomic<int64_t> phase_adjust_{0};
  std::atomic<uint64_t> good_cycles_{0};
  std::atomic<bool> al_changed_{false};
  std::atomic<uint16_t> fault_wkc_{0};
  std::atomic<uint32_t> fault_bad_{0};
  std::atomic<bool> fault_lost_{false};
  std::atomic<int32_t> bad_wkc_{-1};  // last wrong working counter of the current bad streak

  std::atomic<BusPhase> phase_{BusPhase::Down};
  std::atomic<bool> restart_requested_{false};
  mutable std::mutex fault_mutex_;
  std::string fault_text_;

  // worker
  std::thread worker_;
  std::atomic<bool> stop_{false};
  std::thread::id worker_id_;
  std::mutex jobs_mutex_;
  std::condition_variable jobs_cv_;
  std::deque<std::function<void()>> jobs_;
  std::array<RtRequest, 16> rt_{};
  bool fault_reported_ = false;
};

}  // namespace cnc::ethercat
