// The CANopen master of one bus (CiA 301 / 302-2). Two halves, each with
// its own transport so they never share one:
//   - cyclic (servo thread, realtime-safe, no allocation): read() takes the
//     TPDOs that answered the last SYNC into the input image; write() sends
//     the RPDOs from the output image, then SYNC (with counter).
//   - acyclic (its own thread, or poll() in tests): NMT, the boot of every
//     node (identity check 0x1000/0x1018, configuration download, read-back
//     verification, start), SDO clients for all nodes at once, heartbeat
//     producer and consumer, EMCY consumer into the error channel.
// One-cycle transport delay, made explicit: outputs written in cycle k are
// applied by the devices at the SYNC that ends cycle k; inputs read in cycle
// k+1 were sampled at that same SYNC. So feedback read in a cycle belongs to
// the SYNC at which the previous cycle's outputs took effect
// (transport_delay_cycles() == 1, and CyclicStatus tells the SYNC serials).
#pragma once

#include <array>
#include <atomic>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "core/util/process_slot.hpp"
#include "fieldbus/can/transport.hpp"
#include "fieldbus/canopen/config.hpp"
#include "fieldbus/canopen/sdo_client.hpp"

namespace cnc {
class MessageQueue;
}

namespace cnc::canopen {

enum class BootState : uint8_t { Idle, Running, Succeeded, Failed };
const char* to_string(BootState s) noexcept;

// Readable from any thread (atomics behind it).
struct NodeStatus {
  uint8_t id = 0;
  NmtState state = NmtState::Unknown;  // last heartbeat / boot-up
  bool booted = false;                 // boot sequence done, in the cycle
  bool operational = false;            // booted and reporting Operational
  bool fault = false;                  // heartbeat lost, reset, left Operational, PDOs missing
  bool heartbeat_lost = false;
  uint16_t emcy_code = 0;              // last EMCY (0 after an error reset)
  uint8_t error_register = 0;
  uint32_t emcy_count = 0;
  uint32_t pdo_missed = 0;             // TPDOs that did not answer their SYNC
};

// Servo-thread view of the cyclic exchange (read it from the servo thread).
struct CyclicStatus {
  uint64_t sync_serial = 0;        // SYNCs sent so far
  uint8_t sync_counter = 0;        // counter byte of the last SYNC (0 without counter)
  bool inputs_fresh = false;       // every synchronous TPDO answered the last SYNC
  uint64_t inputs_sync_serial = 0; // SYNC at which the oldest current input was sampled
  uint32_t send_errors = 0;        // RPDO/SYNC/heartbeat frames the transport refused
  bool interface_down = false;     // the last send found the interface down (SendStatus::Down)
  uint32_t reads_without_sync = 0; // consecutive cycles in which no SYNC went out (write not running)
  uint32_t pdo_missed = 0;
  uint32_t pdo_length_errors = 0;
  uint32_t rx_overruns = 0;
  can::BusState bus_state = can::BusState::ErrorActive;
};

// A realtime SDO request (expedited, at most 4 bytes), answered by the
// acyclic thread; see Master::rt_sdo_*.
struct RtSdoResult {
  uint32_t abort_code = 0;
  uint32_t value = 0;
  uint8_t size = 0;
};

class Master {
 public:
  static constexpr std::size_t kMaxRtSdo = 16;

  // Opens two transports on config.interface. Throws (configuration,
  // interface) std::runtime_error.
  Master(BusConfig config, MessageQueue* messages);
  // With given transports (tests, custom interfaces).
  Master(BusConfig config, std::unique_ptr<can::Transport> cyclic, std::unique_ptr<can::Transport> acyclic,
         MessageQueue* messages);
  ~Master();
  Master(const Master&) = delete;
  Master& operator=(const Master&) = delete;

  const BusConfig& config() const noexcept { return config_; }
  const std::string& name() const noexcept { return config_.name; }
  // The SYNC period, once the thread that runs the bus is known (before the
  // boot); re-checks the plan (bus load). Throws std::runtime_error.
  void set_cycle_ns(int64_t ns);

  // ---- acyclic side ----
  void start_thread();
  void stop_thread();
  bool thread_running() const noexcept { return thread_.joinable(); }
  // One step of the acyclic engine at time now_ns (tests drive it by hand).
  void poll(int64_t now_ns);
  // Starts the boot of every node (posted to the acyclic side).
  void begin_boot();
  BootState boot_state() const noexcept { return boot_state_.load(std::memory_order_acquire); }
  // Why the boot failed: "node 3 (x-axis): identity 0x1018:01 ...".
  std::string boot_error() const;
  // Runs the boot and waits for it (the thread must run). Throws
  // std::runtime_error "<bus>: start-up stopped: <node>: <object>: <reason>".
  void boot();
  // Re-runs one node's boot (after it reset or was replaced), in the background.
  void reboot_node(uint8_t node);
  // The same, requested from the servo thread (no allocation): the acyclic
  // side picks the request up on its next step.
  void request_reboot(uint8_t node) noexcept;
  // NMT command to one node (0 = all), sent by the acyclic side.
  void nmt(NmtCommand command, uint8_t node);

  // SDO from any non-realtime thread; `done` runs in the acyclic thread.
  // SDO request frames that waited for a later cycle to stay inside the
  // plan's SDO share (acyclic thread's count; read it when the bus is idle).
  uint64_t sdo_frames_deferred() const noexcept { return sdo_pacer_.deferred(); }
  void sdo_upload(uint8_t node, ObjectAddress a, SdoClient::Done done, SdoMode mode = SdoMode::Auto);
  void sdo_download(uint8_t node, ObjectAddress a, std::vector<uint8_t> data, SdoClient::Done done,
                    SdoMode mode = SdoMode::Auto);
  // Blocking forms (never from the acyclic thread or a `done` callback).
  SdoResult sdo_upload_wait(uint8_t node, ObjectAddress a, SdoMode mode = SdoMode::Auto);
  SdoResult sdo_download_wait(uint8_t node, ObjectAddress a, std::vector<uint8_t> data, SdoMode mode = SdoMode::Auto);

  // ---- cyclic side (servo thread) ----
  void cyclic_read(int64_t now_ns) noexcept;
  void cyclic_write(int64_t now_ns) noexcept;
  // false: write() sends nothing (no SYNC, no RPDO); the boot enables it.
  void set_cyclic_enabled(bool on) noexcept { cyclic_enabled_.store(on, std::memory_order_release); }
  // Booted, and the write side sends SYNCs: false once kSyncStallReads
  // reads in a row found no SYNC sent since the previous one (canopen.N.write
  // removed or disabled): the nodes then get no set-points.
  bool is_cyclic_running() const noexcept;
  static constexpr uint32_t kSyncStallReads = 3;
  const CyclicStatus& cyclic_status() const noexcept { return cyclic_; }
  // True once cyclic_write() has run: the heartbeat is the cycle's from then on.
  bool heartbeat_in_cycle() const noexcept { return heartbeat_in_cycle_.load(std::memory_order_acquire); }
  static constexpr int transport_delay_cycles() noexcept { return 1; }

  // Process data of a node, found once (non-realtime) and used each cycle.
  // Outputs: objects the master writes (RPDO); inputs: objects it reads (TPDO).
  ProcessSlot output(uint8_t node, uint16_t index, uint8_t sub) const noexcept;
  ProcessSlot input(uint8_t node, uint16_t index, uint8_t sub) const noexcept;
  // The arrival order of the TPDO that last filled an input slot (larger =
  // later, counted over every TPDO of the bus; 0: never received or not a
  // TPDO slot). Servo thread, no allocation.
  uint64_t input_sequence(const ProcessSlot& s) const noexcept;
  // SYNC serial at which this node's inputs were last sampled (servo thread).
  uint64_t inputs_sync_serial(uint8_t node) const noexcept;

  // Realtime SDO (expedited, <= 4 bytes): returns a handle or -1 when all
  // kMaxRtSdo slots are busy; rt_sdo_poll() returns true once, with the result.
  int rt_sdo_read(uint8_t node, ObjectAddress a) noexcept;
  int rt_sdo_write(uint8_t node, ObjectAddress a, uint32_t value, uint8_t size) noexcept;
  bool rt_sdo_poll(int handle, RtSdoResult& out) noexcept;

  // ---- status (any thread) ----
  std::size_t node_count() const noexcept { return nodes_.size(); }
  NodeStatus node_status_at(std::size_t i) const noexcept;
  NodeStatus node_status(uint8_t node) const noexcept;
  bool is_ready() const noexcept;   // booted, every mandatory node operational and healthy
  // The bus's clock (Transport::now_ns), and the time of the acyclic side's
  // last step in it: how far that side lags the bus (a harness that steps a
  // simulated bus faster than real time waits for it).
  int64_t bus_now_ns() const noexcept { return acyclic_port_->now_ns(); }
  int64_t last_poll_ns() const noexcept { return last_poll_seen_ns_.load(std::memory_order_acquire); }
  bool has_fault() const noexcept;  // a mandatory node faulted, the bus is off or the interface down

 private:
  struct NodeRt;
  struct Step;
  struct RtSdoSlot {
    std::atomic<int> state{0};  // 0 free, 1 claimed, 2 requested, 3 running, 4 done
    uint8_t node = 0;
    ObjectAddress addr;
    bool write = false;
    uint32_t value = 0;
    uint8_t size = 0;
    RtSdoResult result;
  };

  void init();
  void build_steps(NodeRt& n);
  void handle_frame(const can::Frame& f, int64_t now_ns);
  void handle_heartbeat(NodeRt& n, uint8_t state, int64_t now_ns);
  void handle_emcy(uint8_t node, const can::Frame& f);
  void run_boot(int64_t now_ns);
  void boot_node(NodeRt& n, int64_t now_ns);
  void continue_reboot(NodeRt& n, int64_t now_ns);
  void node_failed(NodeRt& n, const std::string& why);
  void send_nmt(NmtCommand c, uint8_t node);
  void service_rt_sdo();
  void post(std::function<void(int64_t)> job);
  void thread_main();
  NodeRt* find(uint8_t node) const noexcept;
  void message(bool error, const std::string& source, const std::string& text);
  void set_fault(NodeRt& n, const std::string& why);
  void write_process_data() noexcept;
  void produce_heartbeat(int64_t now_ns) noexcept;
  bool cyclic_send(const can::Frame& f) noexcept;

  BusConfig config_;
  MessageQueue* messages_;
  std::unique_ptr<can::Transport> cyclic_port_;
  std::unique_ptr<can::Transport> acyclic_port_;
  // The SDO share of the bus-load plan, for every node's SDO client:
  // SDO_FRAMES_PER_CYCLE / 2 requests a cycle (0: unpaced).
  SdoPacer sdo_pacer_{config_.cycle_ns, (config_.plan_sdo_frames + 1) / 2};
  std::vector<std::unique_ptr<NodeRt>> nodes_;

  // acyclic
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::thread::id acyclic_thread_id_;
  std::mutex post_mutex_;
  std::vector<std::function<void(int64_t)>> posted_;
  std::atomic<BootState> boot_state_{BootState::Idle};
  mutable std::mutex boot_mutex_;
  std::condition_variable boot_cv_;
  std::string boot_error_;
  bool booting_ = false;
  bool start_sent_ = false;
  int64_t boot_started_ns_ = 0;
  int64_t next_heartbeat_ns_ = 0;
  int64_t last_poll_ns_ = 0;
  std::atomic<int64_t> last_poll_seen_ns_{0};  // last_poll_ns_ once the step is done, for other threads

  // cyclic
  std::atomic<bool> cyclic_enabled_{false};
  struct TpdoRt;
  struct RpdoRt;
  std::vector<TpdoRt> tpdos_;
  std::vector<RpdoRt> rpdos_;
  std::array<int16_t, 2048> tpdo_by_cob_{};
  CyclicStatus cyclic_;
  uint64_t cycle_ = 0;
  uint64_t rx_sequence_ = 0;  // TPDOs received so far (servo thread)
  can::BusStateTracker bus_tracker_;
  std::atomic<uint64_t> sync_serial_{0};
  std::atomic<int> bus_state_{0};
  std::atomic<bool> heartbeat_in_cycle_{false};  // set by the first cyclic_write, never cleared
  int64_t next_cyclic_heartbeat_ns_ = 0;
  std::atomic<bool> interface_down_{false};
  std::atomic<uint32_t> send_errors_{0};       // cyclic_.send_errors for the acyclic thread
  std::atomic<uint8_t> last_send_error_{0};    // SendStatus of the last refused send
  std::atomic<uint32_t> consecutive_send_errors_{0};  // refused sends since the last accepted one
  // acyclic: when any frame from the bus came last, the send errors then,
  // and whether the interface's silence has been reported.
  int64_t last_rx_ns_ = 0;
  uint32_t send_errors_at_rx_ = 0;
  bool silence_reported_ = false;
  uint64_t last_read_serial_ = 0;
  uint64_t last_read_cycle_ = 0;  // cycle_ (write_process_data calls) at the previous read
  std::atomic<bool> sync_stalled_{false};
  bool sync_stall_reported_ = false;

  std::array<RtSdoSlot, kMaxRtSdo> rt_sdo_{};
};

}  // namespace cnc::canopen
