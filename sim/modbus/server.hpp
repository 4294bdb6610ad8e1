// The Modbus simulator's server: one simulated device (a VFD of a family,
// or a remote I/O module) answering on TCP loopback or on a pseudo-terminal
// pair for RTU, on libmodbus's server side (the Huanyang family's own
// frames are parsed here). Faults are injected on request: an over-current
// trip, a silent slave, wrong CRCs, exception answers, a dropped TCP
// connection. Optionally emulates the serial line's frame time on the pty.
// Not product code (sim/ only); runs its own thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

#include "sim/modbus/device.hpp"

typedef struct _modbus modbus_t;

namespace cnc::modbus_sim {

struct ServerConfig {
  Family family = Family::Delta;
  uint8_t slave = 1;
  bool tcp = true;        // false: RTU on a pty
  int port = 0;           // TCP port on 127.0.0.1 (0: the kernel picks one)
  int line_baud = 0;      // RTU: >0 delays each answer by the line time of request and answer
  int bits_per_char = 10; // 8N1
  MotorParams motor;
};

struct ServerStats {
  uint64_t requests = 0;     // frames received for this slave
  uint64_t answered = 0;
  uint64_t bad_frames = 0;   // Huanyang frames with a wrong CRC or length
};

class Server {
 public:
  explicit Server(ServerConfig c);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  // Opens the endpoint (throws std::runtime_error) and starts the thread.
  void start();
  void stop();

  int port() const noexcept { return port_; }                 // TCP
  const std::string& pty_path() const noexcept { return pty_path_; }  // RTU: the client's device

  // Fault injection (any thread).
  void trip_overcurrent();
  void set_silent(bool on) { silent_.store(on); }
  void set_bad_crc(int answers) { bad_crc_.store(answers); }          // RTU only
  void set_exception(uint8_t code, int answers) {                     // code 0: off; answers < 0: until cleared
    exception_code_.store(code);
    exception_left_.store(answers);
  }
  void drop_connection() { drop_.store(true); }                       // TCP
  void clear_faults();

  // Runs `f` on the device under the server's lock (tests, command line).
  void with_device(const std::function<void(Device&)>& f);
  ServerStats stats();

 private:
  void run_tcp();
  void run_rtu();
  void run_huanyang();
  void serve_request(const uint8_t* req, int len);
  bool take_exception(uint8_t& code);
  void write_bad_crc_reply(const uint8_t* req, int len);
  void line_delay(std::size_t req_bytes, std::size_t reply_bytes);

  ServerConfig c_;
  Device device_;
  std::mutex mutex_;
  ServerStats stats_;
  modbus_t* ctx_ = nullptr;
  int listen_fd_ = -1;
  int master_fd_ = -1;   // pty master (the simulator's end)
  int slave_keep_fd_ = -1;  // held open so the master never sees a hang-up
  int port_ = 0;
  std::string pty_path_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> silent_{false};
  std::atomic<int> bad_crc_{0};
  std::atomic<uint8_t> exception_code_{0};
  std::atomic<int> exception_left_{0};
  std::atomic<bool> drop_{false};
};

}  // namespace cnc::modbus_sim
