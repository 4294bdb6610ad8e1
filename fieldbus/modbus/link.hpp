// One Modbus link (an RS-485 line or a TCP connection) and the devices on
// it, polled by the link's own non-realtime thread. The servo thread only
// exchanges mailboxes with it (VfdPort, IoPort): sequence locks it writes
// or reads once per cycle without waiting, each value carrying the time it
// was last exchanged. The thread counts timeouts, CRC errors, exception
// answers and silent slaves, retries with back-off, reconnects without a
// restart and says what happened on the message channel.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "core/util/fixed_string.hpp"
#include "core/util/seqlock.hpp"
#include "fieldbus/modbus/config.hpp"

typedef struct _modbus modbus_t;

namespace cnc {
class MessageQueue;
}

namespace cnc::modbus {

// Servo thread -> link: what a VFD should do.
struct VfdCommand {
  bool run = false;
  bool reverse = false;
  double speed_rpm = 0;     // magnitude
  uint32_t reset_count = 0; // a new value asks for one fault reset
};

// Link -> servo thread: what the VFD reported, each value with the
// monotonic time it was read (0: never).
struct VfdFeedback {
  double frequency_hz = 0;  // output frequency (magnitude)
  double current_a = 0;
  uint16_t fault_code = 0;  // 0: no fault
  bool reverse = false;     // direction it was last commanded
  int64_t frequency_ns = 0;
  int64_t current_ns = 0;
  int64_t ok_ns = 0;        // last complete exchange
  int64_t command_ns = 0;   // last time the command was written
};

// Fault and traffic counters per device, readable from any thread.
struct DeviceCounters {
  std::atomic<uint32_t> exchanges{0};  // successful requests
  std::atomic<uint32_t> timeouts{0};
  std::atomic<uint32_t> crc_errors{0};
  std::atomic<uint32_t> exceptions{0};
  std::atomic<uint32_t> other_errors{0};
  std::atomic<uint32_t> last_exception{0};  // Modbus exception code
  std::atomic<int64_t> last_latency_ns{0};
  std::atomic<int64_t> max_latency_ns{0};
};

struct VfdPort {
  VfdConfig config;
  SeqLock<VfdCommand> command;    // written by the servo thread
  SeqLock<VfdFeedback> feedback;  // written by the link thread
  DeviceCounters counters;
  // The decoded text of the drive's fault or of the lost communication,
  // for the status panel (task cycle) only.
  SeqLock<FixedString<96>> fault_text;
};

struct IoInputs {
  std::array<double, kMaxIoValues> value{};   // bits as 0/1, registers scaled
  std::array<int64_t, kMaxIoMaps> map_ns{};   // per polling group: time read (inputs) or written (outputs)
};
struct IoOutputs {
  std::array<double, kMaxIoValues> value{};
};

struct IoPort {
  IoConfig config;
  SeqLock<IoOutputs> outputs;  // servo thread -> link
  SeqLock<IoInputs> inputs;    // link -> servo thread
  DeviceCounters counters;
};

struct LinkCounters {
  std::atomic<bool> connected{false};
  std::atomic<uint32_t> connects{0};
  std::atomic<uint32_t> connect_failures{0};
  std::atomic<uint64_t> cycles{0};  // passes over every due device
};

class Link {
 public:
  Link(LinkConfig config, MessageQueue* messages);
  ~Link();
  Link(const Link&) = delete;
  Link& operator=(const Link&) = delete;

  const LinkConfig& config() const noexcept { return config_; }
  const std::string& name() const noexcept { return config_.name; }
  std::vector<std::unique_ptr<VfdPort>>& vfds() noexcept { return vfds_; }
  std::vector<std::unique_ptr<IoPort>>& ios() noexcept { return ios_; }
  const LinkCounters& counters() const noexcept { return counters_; }

  void start();
  void stop();
  // Writes stop to every VFD now (from the link thread) and waits for it,
  // at most `timeout_ns`; true when every VFD answered. From then on the
  // link keeps the VFDs stopped whatever the servo thread commands (the
  // controller is shutting down).
  bool stop_drives(int64_t timeout_ns);

 private:
  struct VfdState;
  struct IoState;
  enum class Result { Ok, Timeout, Crc, Exception, Broken, Other };

  void run();
  bool connect(int64_t now);
  void disconnect();
  int64_t poll_vfd(VfdPort& p, VfdState& s, int64_t now);
  int64_t poll_io(IoPort& p, IoState& s, int64_t now);
  bool exchange_vfd(VfdPort& p, VfdState& s, const VfdCommand& cmd, VfdFeedback& fb);
  bool exchange_huanyang(VfdPort& p, VfdState& s, const VfdCommand& cmd, VfdFeedback& fb);
  bool write_words(VfdPort& p, const std::vector<RegisterWrite>& words);
  bool read_scaled(VfdPort& p, const ScaledRegister& r, double& out);
  // Books the outcome of one request of a device (errno from libmodbus).
  bool account(DeviceCounters& c, int rc, int64_t started_ns, const char* what, uint16_t address);
  bool raw_exchange(DeviceCounters& c, const uint8_t* frame, std::size_t size, uint8_t* reply, std::size_t& reply_size);
  void device_failed(const std::string& who, int& streak, int64_t& retry_at, int64_t now, bool& reported);
  void device_ok(const std::string& who, int& streak, bool& reported);
  void post(bool error, const std::string& text);

  LinkConfig config_;
  MessageQueue* messages_;
  std::vector<std::unique_ptr<VfdPort>> vfds_;
  std::vector<std::unique_ptr<IoPort>> ios_;
  std::vector<VfdState> vfd_state_;
  std::vector<IoState> io_state_;
  LinkCounters counters_;
  modbus_t* ctx_ = nullptr;
  std::string last_error_;        // of the last failed request (link thread)
  Result last_result_ = Result::Ok;
  int timeouts_in_row_ = 0;
  int64_t next_connect_ns_ = 0;
  int64_t backoff_ns_ = 0;
  bool connect_reported_ = false;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<uint32_t> stop_drives_request_{0};
  std::atomic<uint32_t> stop_drives_done_{0};
  std::atomic<bool> stop_drives_ok_{false};
  std::atomic<bool> hold_stopped_{false};
};

}  // namespace cnc::modbus
