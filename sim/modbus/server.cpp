#include "sim/modbus/server.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "core/util/time.hpp"
#include "fieldbus/modbus/crc.hpp"

namespace cnc::modbus_sim {
namespace {

uint16_t be16(const uint8_t* p) { return static_cast<uint16_t>((p[0] << 8) | p[1]); }

bool wait_readable(int fd, int ms) {
  pollfd p{fd, POLLIN, 0};
  return ::poll(&p, 1, ms) > 0 && (p.revents & (POLLIN | POLLHUP | POLLERR));
}

void append_crc(std::vector<uint8_t>& f, bool corrupt) {
  uint16_t c = modbus::crc16(f.data(), f.size());
  if (corrupt) c ^= 0xFFFF;
  f.push_back(static_cast<uint8_t>(c & 0xFF));
  f.push_back(static_cast<uint8_t>(c >> 8));
}

}  // namespace

Server::Server(ServerConfig c) : c_(c), device_(c.family, c.motor) {}

Server::~Server() {
  stop();
  if (ctx_) modbus_free(ctx_);
  if (listen_fd_ >= 0) ::close(listen_fd_);
  if (master_fd_ >= 0) ::close(master_fd_);
  if (slave_keep_fd_ >= 0) ::close(slave_keep_fd_);
}

void Server::start() {
  if (c_.tcp) {
    if (c_.family == Family::Huanyang) throw std::runtime_error("the Huanyang protocol is RTU only");
    ctx_ = modbus_new_tcp("127.0.0.1", c_.port);
    if (!ctx_) throw std::runtime_error("modbus_new_tcp failed");
    listen_fd_ = modbus_tcp_listen(ctx_, 1);
    if (listen_fd_ < 0) throw std::runtime_error(std::string("cannot listen on 127.0.0.1: ") + modbus_strerror(errno));
    sockaddr_in a{};
    socklen_t len = sizeof a;
    getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&a), &len);
    port_ = ntohs(a.sin_port);
  } else {
    master_fd_ = posix_openpt(O_RDWR | O_NOCTTY);
    if (master_fd_ < 0 || grantpt(master_fd_) != 0 || unlockpt(master_fd_) != 0) {
      throw std::runtime_error(std::string("cannot create a pseudo-terminal: ") + std::strerror(errno));
    }
    pty_path_ = ptsname(master_fd_);
    slave_keep_fd_ = ::open(pty_path_.c_str(), O_RDWR | O_NOCTTY);
    termios t{};
    tcgetattr(slave_keep_fd_, &t);
    cfmakeraw(&t);
    tcsetattr(slave_keep_fd_, TCSANOW, &t);
    if (c_.family != Family::Huanyang) {
      ctx_ = modbus_new_rtu(pty_path_.c_str(), 19200, 'N', 8, 1);
      if (!ctx_) throw std::runtime_error("modbus_new_rtu failed");
      modbus_set_slave(ctx_, c_.slave);
      modbus_set_socket(ctx_, master_fd_);  // the server's end of the pair
    }
  }
  thread_ = std::thread([this] {
    if (c_.tcp) run_tcp();
    else if (c_.family == Family::Huanyang) run_huanyang();
    else run_rtu();
  });
}

void Server::stop() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
}

void Server::trip_overcurrent() {
  std::lock_guard<std::mutex> lock(mutex_);
  device_.model().trip_overcurrent();
}

void Server::clear_faults() {
  silent_.store(false);
  bad_crc_.store(0);
  exception_code_.store(0);
  exception_left_.store(0);
}

void Server::with_device(const std::function<void(Device&)>& f) {
  std::lock_guard<std::mutex> lock(mutex_);
  device_.model().advance(monotonic_ns());
  f(device_);
}

ServerStats Server::stats() {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

bool Server::take_exception(uint8_t& code) {
  code = exception_code_.load();
  if (code == 0) return false;
  const int left = exception_left_.load();
  if (left == 0) return false;
  if (left > 0) exception_left_.store(left - 1);
  return true;
}

void Server::line_delay(std::size_t req_bytes, std::size_t reply_bytes) {
  if (c_.tcp || c_.line_baud <= 0) return;
  // Both frames on the wire plus the 3.5-character silences that end them.
  const double chars = static_cast<double>(req_bytes + reply_bytes) + 7.0;
  const auto ns = static_cast<int64_t>(chars * c_.bits_per_char * 1e9 / c_.line_baud);
  const timespec ts = to_timespec(ns);
  nanosleep(&ts, nullptr);
}

// A reply with the right shape and a wrong CRC (RTU).
void Server::write_bad_crc_reply(const uint8_t* req, int len) {
  std::vector<uint8_t> f(req, req + std::min(len - 2, 6));
  const uint8_t fc = req[1];
  if (fc == 3 || fc == 4) {
    const uint16_t n = be16(req + 4);
    f.assign({req[0], fc, static_cast<uint8_t>(2 * n)});
    for (uint16_t i = 0; i < 2 * n; ++i) f.push_back(0);
  }
  append_crc(f, true);
  line_delay(static_cast<std::size_t>(len), f.size());
  (void)!::write(master_fd_, f.data(), f.size());
}

void Server::serve_request(const uint8_t* req, int len) {
  const int off = modbus_get_header_length(ctx_);
  const uint8_t fc = req[off];
  std::lock_guard<std::mutex> lock(mutex_);
  ++stats_.requests;
  if (silent_.load()) return;
  if (!c_.tcp && bad_crc_.load() > 0) {
    bad_crc_.fetch_sub(1);
    write_bad_crc_reply(req, len);
    return;
  }
  uint8_t code = 0;
  if (take_exception(code)) {
    line_delay(static_cast<std::size_t>(len), 5);
    modbus_reply_exception(ctx_, req, code);
    ++stats_.answered;
    return;
  }
  device_.model().advance(monotonic_ns());
  const uint16_t addr = be16(req + off + 1);
  const uint16_t count = (fc == 5 || fc == 6) ? 1 : be16(req + off + 3);
  bool ok = count >= 1 && count <= 125;
  // A mapping covering exactly the request, filled from (or applied to) the device.
  modbus_mapping_t* map = nullptr;
  switch (fc) {
    case 1:
    case 5:
    case 15: map = modbus_mapping_new_start_address(addr, count, 0, 0, 0, 0, 0, 0); break;
    case 2: map = modbus_mapping_new_start_address(0, 0, addr, count, 0, 0, 0, 0); break;
    case 3:
    case 6:
    case 16: map = modbus_mapping_new_start_address(0, 0, 0, 0, addr, count, 0, 0); break;
    case 4: map = modbus_mapping_new_start_address(0, 0, 0, 0, 0, 0, addr, count); break;
    default: ok = false;
  }
  for (uint16_t i = 0; ok && i < count; ++i) {
    const uint16_t a = static_cast<uint16_t>(addr + i);
    switch (fc) {
      case 1: ok = device_.read_coil(a, map->tab_bits[i]); break;
      case 2: ok = device_.read_discrete(a, map->tab_input_bits[i]); break;
      case 3: ok = device_.read_holding(a, map->tab_registers[i]); break;
      case 4: ok = device_.read_input(a, map->tab_input_registers[i]); break;
      case 5: ok = device_.write_coil(a, be16(req + off + 3) == 0xFF00); break;
      case 6: ok = device_.write_holding(a, be16(req + off + 3)); break;
      case 15: ok = device_.write_coil(a, (req[off + 6 + i / 8] >> (i % 8)) & 1); break;
      case 16: ok = device_.write_holding(a, be16(req + off + 6 + 2 * i)); break;
    }
  }
  std::size_t reply_bytes = 8;
  if (fc == 3 || fc == 4) reply_bytes = 5 + 2U * count;
  line_delay(static_cast<std::size_t>(len), reply_bytes);
  if (!ok) {
    modbus_reply_exception(ctx_, req, fc <= 16 && map ? MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS : MODBUS_EXCEPTION_ILLEGAL_FUNCTION);
  } else {
    modbus_reply(ctx_, req, len, map);
  }
  ++stats_.answered;
  if (map) modbus_mapping_free(map);
}

void Server::run_tcp() {
  uint8_t req[MODBUS_TCP_MAX_ADU_LENGTH];
  while (!stop_.load()) {
    if (!wait_readable(listen_fd_, 20)) continue;
    int fd = listen_fd_;
    if (modbus_tcp_accept(ctx_, &fd) < 0) continue;
    drop_.store(false);
    while (!stop_.load()) {
      if (drop_.exchange(false)) break;
      if (!wait_readable(modbus_get_socket(ctx_), 20)) continue;
      const int len = modbus_receive(ctx_, req);
      if (len < 0) break;  // the client closed the connection
      if (len == 0) continue;
      serve_request(req, len);
    }
    ::close(modbus_get_socket(ctx_));
    modbus_set_socket(ctx_, -1);
  }
}

void Server::run_rtu() {
  uint8_t req[MODBUS_RTU_MAX_ADU_LENGTH];
  while (!stop_.load()) {
    if (!wait_readable(master_fd_, 20)) continue;
    const int len = modbus_receive(ctx_, req);
    if (len <= 0) {
      // CRC errors, frames for other slaves: forget what is buffered.
      tcflush(master_fd_, TCIFLUSH);
      continue;
    }
    serve_request(req, len);
  }
}

// The Huanyang frames: slave, function, length, data[length], CRC.
void Server::run_huanyang() {
  uint8_t buf[64];
  while (!stop_.load()) {
    if (!wait_readable(master_fd_, 20)) continue;
    std::size_t got = 0, want = 3;
    bool complete = true;
    while (got < want) {
      if (got > 0 && !wait_readable(master_fd_, 50)) {
        complete = false;
        break;
      }
      const ssize_t n = ::read(master_fd_, buf + got, want - got);
      if (n <= 0) {
        complete = false;
        break;
      }
      got += static_cast<std::size_t>(n);
      if (want == 3 && got >= 3) want = std::min<std::size_t>(3U + buf[2] + 2U, sizeof buf);
    }
    std::lock_guard<std::mutex> lock(mutex_);
    if (!complete || !modbus::crc_ok(buf, got)) {
      ++stats_.bad_frames;
      continue;
    }
    if (buf[0] != c_.slave) continue;
    ++stats_.requests;
    if (silent_.load()) continue;
    VfdModel& m = device_.model();
    m.advance(monotonic_ns());
    std::vector<uint8_t> reply = {buf[0], buf[1]};
    switch (buf[1]) {
      case 0x03: {  // control: answer the control status byte
        const uint8_t ctl = buf[3];
        if (ctl == 0x08) m.command(false, m.reverse());
        else if (ctl == 0x01) m.command(true, false);
        else if (ctl == 0x11) m.command(true, true);
        const uint8_t st = static_cast<uint8_t>((m.run() ? 0x08 : 0) | (m.reverse() ? 0x20 : 0));
        reply.insert(reply.end(), {1, st});
        break;
      }
      case 0x05: {  // frequency in 0.01 Hz, echoed
        m.set_reference_hz(be16(buf + 3) / 100.0);
        reply.insert(reply.end(), {2, buf[3], buf[4]});
        break;
      }
      case 0x04: {
        uint16_t v = 0;
        switch (buf[3]) {
          case 0x00: v = static_cast<uint16_t>(std::lround(m.reference_hz() * 100)); break;
          case 0x01: v = static_cast<uint16_t>(std::lround(std::fabs(m.output_hz()) * 100)); break;
          case 0x02: v = static_cast<uint16_t>(std::lround(m.current_a() * 10)); break;
          case 0x03: v = static_cast<uint16_t>(std::lround(std::fabs(m.output_hz()) * 60)); break;
          default: v = 0;
        }
        reply.insert(reply.end(), {3, buf[3], static_cast<uint8_t>(v >> 8), static_cast<uint8_t>(v & 0xFF)});
        break;
      }
      default: continue;  // the HY answers nothing it does not know
    }
    const bool corrupt = bad_crc_.load() > 0;
    if (corrupt) bad_crc_.fetch_sub(1);
    append_crc(reply, corrupt);
    line_delay(got, reply.size());
    (void)!::write(master_fd_, reply.data(), reply.size());
    ++stats_.answered;
  }
}

}  // namespace cnc::modbus_sim
