#include "fieldbus/modbus/link.hpp"

#include <modbus/modbus.h>
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>

#include "core/util/messages.hpp"
#include "core/util/time.hpp"
#include "fieldbus/modbus/huanyang.hpp"

namespace cnc::modbus {
namespace {

constexpr int64_t kRefreshNs = 1'000'000'000;  // commands are rewritten at least this often
constexpr int64_t kIdleNs = 5'000'000;         // longest sleep: stop requests are seen within it
constexpr int kTimeoutsBeforeReconnect = 3;    // TCP: a silent connection is reopened

void sleep_until(int64_t t) {
  const timespec ts = to_timespec(t);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

uint16_t to_raw(double v) {
  const double r = std::round(v);
  return static_cast<uint16_t>(std::clamp(r, 0.0, 65535.0));
}

bool is_exception(int err) { return err >= EMBXILFUN && err <= EMBXGTAR; }

bool is_broken(int err) {
  return err == ECONNRESET || err == EPIPE || err == EBADF || err == ENOTCONN || err == ECONNREFUSED || err == EIO ||
         err == ENXIO || err == ENODEV;
}

}  // namespace

struct Link::VfdState {
  int64_t next_poll_ns = 0;
  int64_t retry_at_ns = 0;
  int fail_streak = 0;
  bool reported = false;
  bool need_on_connect = true;
  bool written = false;
  bool last_run = false;
  bool last_reverse = false;
  uint16_t last_speed_raw = 0;
  int64_t last_write_ns = 0;
  uint32_t reset_seen = 0;
  bool reset_primed = false;
  uint16_t last_fault = 0;
  VfdFeedback fb;
};

struct Link::IoState {
  std::array<int64_t, kMaxIoMaps> next_ns{};
  int64_t retry_at_ns = 0;
  int fail_streak = 0;
  bool reported = false;
  IoInputs in;
};

Link::Link(LinkConfig config, MessageQueue* messages) : config_(std::move(config)), messages_(messages) {
  for (const VfdConfig& v : config_.vfds) {
    auto p = std::make_unique<VfdPort>();
    p->config = v;
    vfds_.push_back(std::move(p));
  }
  for (const IoConfig& c : config_.ios) {
    auto p = std::make_unique<IoPort>();
    p->config = c;
    ios_.push_back(std::move(p));
  }
  vfd_state_.resize(vfds_.size());
  io_state_.resize(ios_.size());
  backoff_ns_ = config_.retry_min_ns;
}

Link::~Link() {
  stop();
  disconnect();
  if (ctx_) modbus_free(ctx_);
}

void Link::start() {
  if (thread_.joinable()) return;
  stop_.store(false);
  thread_ = std::thread([this] { run(); });
}

void Link::stop() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
}

bool Link::stop_drives(int64_t timeout_ns) {
  if (!thread_.joinable() || vfds_.empty()) return vfds_.empty();
  hold_stopped_.store(true);
  const uint32_t req = stop_drives_request_.fetch_add(1) + 1;
  const int64_t deadline = monotonic_ns() + timeout_ns;
  while (stop_drives_done_.load() != req) {
    if (monotonic_ns() > deadline) return false;
    usleep(1000);
  }
  return stop_drives_ok_.load();
}

void Link::post(bool error, const std::string& text) {
  if (messages_) messages_->post(error ? MessageKind::Error : MessageKind::Text, config_.name, text);
}

bool Link::connect(int64_t now) {
  if (!ctx_) {
    if (config_.transport == Transport::Tcp) {
      ctx_ = modbus_new_tcp_pi(config_.host.c_str(), std::to_string(config_.port).c_str());
    } else {
      ctx_ = modbus_new_rtu(config_.device.c_str(), config_.baud, config_.parity, config_.data_bits, config_.stop_bits);
    }
    if (!ctx_) {
      last_error_ = std::string("cannot create the libmodbus context: ") + modbus_strerror(errno);
      next_connect_ns_ = now + config_.retry_max_ns;
      if (!connect_reported_) post(true, config_.describe() + ": " + last_error_);
      connect_reported_ = true;
      return false;
    }
    const auto sec = static_cast<uint32_t>(config_.timeout_ns / 1'000'000'000);
    const auto usec = static_cast<uint32_t>((config_.timeout_ns % 1'000'000'000) / 1000);
    modbus_set_response_timeout(ctx_, sec, usec);
    modbus_set_byte_timeout(ctx_, sec, usec);
  }
  if (modbus_connect(ctx_) == -1) {
    const int err = errno;
    counters_.connect_failures.fetch_add(1, std::memory_order_relaxed);
    if (!connect_reported_) {
      post(true, "cannot connect (" + config_.describe() + "): " + modbus_strerror(err) + "; retrying every " +
                     std::to_string(config_.retry_min_ns / 1'000'000) + " to " +
                     std::to_string(config_.retry_max_ns / 1'000'000) + " ms");
      connect_reported_ = true;
    }
    next_connect_ns_ = now + backoff_ns_;
    backoff_ns_ = std::min(backoff_ns_ * 2, config_.retry_max_ns);
    return false;
  }
  if (config_.transport == Transport::Rtu) modbus_flush(ctx_);
  const uint32_t n = counters_.connects.fetch_add(1, std::memory_order_relaxed) + 1;
  counters_.connected.store(true, std::memory_order_release);
  backoff_ns_ = config_.retry_min_ns;
  timeouts_in_row_ = 0;
  if (connect_reported_ || n > 1) post(false, "connected (" + config_.describe() + ")");
  connect_reported_ = false;
  for (VfdState& s : vfd_state_) {
    s.need_on_connect = true;
    s.written = false;
  }
  return true;
}

void Link::disconnect() {
  if (ctx_ && counters_.connected.load()) modbus_close(ctx_);
  counters_.connected.store(false, std::memory_order_release);
}

bool Link::account(DeviceCounters& c, int rc, int64_t started_ns, const char* what, uint16_t address) {
  const int64_t latency = monotonic_ns() - started_ns;
  if (rc >= 0) {
    c.exchanges.fetch_add(1, std::memory_order_relaxed);
    c.last_latency_ns.store(latency, std::memory_order_relaxed);
    if (latency > c.max_latency_ns.load(std::memory_order_relaxed)) c.max_latency_ns.store(latency, std::memory_order_relaxed);
    timeouts_in_row_ = 0;
    return true;
  }
  const int err = errno;
  char where[64];
  std::snprintf(where, sizeof where, "%s 0x%04X: ", what, address);
  last_error_ = std::string(where) + modbus_strerror(err);
  if (err == ETIMEDOUT) {
    c.timeouts.fetch_add(1, std::memory_order_relaxed);
    ++timeouts_in_row_;
    last_result_ = Result::Timeout;
    last_error_ = std::string(where) + "no answer within " + std::to_string(config_.timeout_ns / 1'000'000) + " ms";
  } else if (err == EMBBADCRC) {
    c.crc_errors.fetch_add(1, std::memory_order_relaxed);
    last_result_ = Result::Crc;
  } else if (is_exception(err)) {
    c.exceptions.fetch_add(1, std::memory_order_relaxed);
    c.last_exception.store(static_cast<uint32_t>(err - MODBUS_ENOBASE), std::memory_order_relaxed);
    last_result_ = Result::Exception;
    last_error_ = std::string(where) + "exception " + std::to_string(err - MODBUS_ENOBASE) + " (" + modbus_strerror(err) + ")";
  } else if (is_broken(err)) {
    c.other_errors.fetch_add(1, std::memory_order_relaxed);
    last_result_ = Result::Broken;
  } else {
    c.other_errors.fetch_add(1, std::memory_order_relaxed);
    last_result_ = Result::Other;
  }
  // Whatever is left of a late or broken answer must not be taken for the
  // next one.
  if (err != ETIMEDOUT || config_.transport == Transport::Rtu) modbus_flush(ctx_);
  return false;
}

bool Link::write_words(VfdPort& p, const std::vector<RegisterWrite>& words) {
  for (const RegisterWrite& w : words) {
    const int64_t t = monotonic_ns();
    if (!account(p.counters, modbus_write_register(ctx_, w.address, w.value), t, "writing", w.address)) return false;
  }
  return true;
}

bool Link::read_scaled(VfdPort& p, const ScaledRegister& r, double& out) {
  uint16_t raw = 0;
  const int64_t t = monotonic_ns();
  const int rc = r.space == Space::Input ? modbus_read_input_registers(ctx_, r.address, 1, &raw)
                                         : modbus_read_registers(ctx_, r.address, 1, &raw);
  if (!account(p.counters, rc, t, "reading", r.address)) return false;
  const double v = r.is_signed ? static_cast<double>(static_cast<int16_t>(raw)) : static_cast<double>(raw);
  out = v / r.per_unit;
  return true;
}

bool Link::exchange_vfd(VfdPort& p, VfdState& s, const VfdCommand& cmd, VfdFeedback& fb) {
  const VfdProfile& pr = p.config.profile;
  const int64_t now = monotonic_ns();
  if (s.need_on_connect) {
    if (!write_words(p, pr.on_connect)) return false;
    s.need_on_connect = false;
  }
  if (!s.reset_primed) {
    s.reset_seen = cmd.reset_count;  // a reset asked before the link ran is not replayed
    s.reset_primed = true;
  }
  if (cmd.reset_count != s.reset_seen) {
    if (!write_words(p, pr.fault_reset)) return false;
    s.reset_seen = cmd.reset_count;
    s.written = false;
  }
  const bool refresh = !s.written || now - s.last_write_ns > kRefreshNs;
  const uint16_t speed_raw = to_raw(cmd.speed_rpm / p.config.rpm_per_hz * pr.speed_per_hz);
  if (refresh || speed_raw != s.last_speed_raw) {
    if (!write_words(p, {{pr.speed_address, speed_raw}})) return false;
    s.last_speed_raw = speed_raw;
  }
  if (refresh || cmd.run != s.last_run || cmd.reverse != s.last_reverse) {
    // A profile without a reverse command stops rather than run forward.
    const auto& words = !cmd.run ? pr.stop : cmd.reverse ? (pr.run_reverse.empty() ? pr.stop : pr.run_reverse) : pr.run_forward;
    if (!write_words(p, words)) return false;
    s.last_run = cmd.run;
    s.last_reverse = cmd.reverse;
  }
  if (refresh) {
    s.written = true;
    s.last_write_ns = now;
  }
  fb.command_ns = now;
  fb.reverse = cmd.reverse;
  if (pr.output_frequency.present) {
    if (!read_scaled(p, pr.output_frequency, fb.frequency_hz)) return false;
    fb.frequency_hz = std::fabs(fb.frequency_hz);
    fb.frequency_ns = monotonic_ns();
  }
  if (pr.current.present) {
    if (!read_scaled(p, pr.current, fb.current_a)) return false;
    fb.current_ns = monotonic_ns();
  }
  if (pr.fault.present) {
    double code = 0;
    const ScaledRegister raw{true, pr.fault.space, pr.fault.address, 1, false};
    if (!read_scaled(p, raw, code)) return false;
    fb.fault_code = static_cast<uint16_t>(static_cast<uint16_t>(code) & pr.fault_mask);
  }
  return true;
}

bool Link::raw_exchange(DeviceCounters& c, const uint8_t* frame, std::size_t size, uint8_t* reply,
                        std::size_t& reply_size) {
  const int64_t t0 = monotonic_ns();
  // libmodbus adds the CRC: it gets the frame without its last two bytes.
  if (modbus_send_raw_request(ctx_, frame, static_cast<int>(size - 2)) < 0) {
    return account(c, -1, t0, "sending function", frame[1]);
  }
  const int fd = modbus_get_socket(ctx_);
  const int64_t deadline = t0 + config_.timeout_ns;
  std::size_t want = 3, got = 0;
  while (got < want) {
    const int64_t left = deadline - monotonic_ns();
    pollfd pfd{fd, POLLIN, 0};
    const int pr = left > 0 ? ::poll(&pfd, 1, static_cast<int>((left + 999'999) / 1'000'000)) : 0;
    if (pr <= 0) {
      errno = pr == 0 ? ETIMEDOUT : errno;
      return account(c, -1, t0, "function", frame[1]);
    }
    const ssize_t n = ::read(fd, reply + got, want - got);
    if (n <= 0) {
      errno = n == 0 ? EIO : errno;
      return account(c, -1, t0, "function", frame[1]);
    }
    got += static_cast<std::size_t>(n);
    if (got >= 3 && want == 3) {
      want = hy::frame_size(reply[2]);
      if (want > 16) {
        errno = EMBBADDATA;
        return account(c, -1, t0, "function", frame[1]);
      }
    }
  }
  reply_size = got;
  const hy::Reply r = hy::parse_reply(reply, got, frame[0], frame[1]);
  if (r.error == hy::ParseError::BadCrc) {
    errno = EMBBADCRC;
    return account(c, -1, t0, "function", frame[1]);
  }
  if (r.error != hy::ParseError::None) {
    errno = EMBBADDATA;
    account(c, -1, t0, "function", frame[1]);
    last_error_ += std::string(" (") + hy::to_string(r.error) + ")";
    return false;
  }
  return account(c, 0, t0, "function", frame[1]);
}

bool Link::exchange_huanyang(VfdPort& p, VfdState& s, const VfdCommand& cmd, VfdFeedback& fb) {
  const VfdProfile& pr = p.config.profile;
  const uint8_t slave = p.config.slave;
  const int64_t now = monotonic_ns();
  uint8_t reply[16];
  std::size_t n = 0;
  const bool refresh = !s.written || now - s.last_write_ns > kRefreshNs;
  const uint16_t speed_raw = to_raw(cmd.speed_rpm / p.config.rpm_per_hz * pr.speed_per_hz);
  if (refresh || speed_raw != s.last_speed_raw) {
    const hy::Frame f = hy::set_frequency(slave, speed_raw);
    if (!raw_exchange(p.counters, f.bytes.data(), f.size, reply, n)) return false;
    s.last_speed_raw = speed_raw;
  }
  if (refresh || cmd.run != s.last_run || cmd.reverse != s.last_reverse) {
    const uint8_t ctl = !cmd.run ? hy::kControlStop : cmd.reverse ? hy::kControlRunReverse : hy::kControlRunForward;
    const hy::Frame f = hy::control(slave, ctl);
    if (!raw_exchange(p.counters, f.bytes.data(), f.size, reply, n)) return false;
    s.last_run = cmd.run;
    s.last_reverse = cmd.reverse;
  }
  if (refresh) {
    s.written = true;
    s.last_write_ns = now;
  }
  fb.command_ns = now;
  fb.reverse = cmd.reverse;
  const std::pair<const ScaledRegister*, double*> reads[] = {{&pr.output_frequency, &fb.frequency_hz},
                                                            {&pr.current, &fb.current_a}};
  for (const auto& [r, out] : reads) {
    if (!r->present) continue;
    const hy::Frame f = hy::read_status(slave, static_cast<uint8_t>(r->address));
    if (!raw_exchange(p.counters, f.bytes.data(), f.size, reply, n)) return false;
    const auto v = hy::monitor_value(hy::parse_reply(reply, n, slave, hy::kReadControlStatus), static_cast<uint8_t>(r->address));
    if (!v) {
      last_error_ = "function 0x04: the reply names another monitor value";
      p.counters.other_errors.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    *out = *v / r->per_unit;
    (r == &pr.current ? fb.current_ns : fb.frequency_ns) = monotonic_ns();
  }
  return true;
}

void Link::device_failed(const std::string& who, int& streak, int64_t& retry_at, int64_t now, bool& reported) {
  ++streak;
  if (streak >= 2) {
    const int shift = std::min(streak - 2, 20);
    retry_at = now + std::min(config_.retry_min_ns << shift, config_.retry_max_ns);
  }
  if (!reported) {
    post(true, who + ": " + last_error_ + "; retrying with back-off");
    reported = true;
  }
}

void Link::device_ok(const std::string& who, int& streak, bool& reported) {
  if (reported) post(false, who + ": communication restored after " + std::to_string(streak) + " failed polls");
  reported = false;
  streak = 0;
}

int64_t Link::poll_vfd(VfdPort& p, VfdState& s, int64_t now) {
  VfdCommand cmd;
  p.command.try_read(cmd);
  if (hold_stopped_.load(std::memory_order_relaxed)) cmd.run = false;
  modbus_set_slave(ctx_, p.config.slave);
  VfdFeedback fb = s.fb;
  const bool ok = p.config.profile.protocol == Protocol::Huanyang ? exchange_huanyang(p, s, cmd, fb)
                                                                   : exchange_vfd(p, s, cmd, fb);
  char who[96];
  std::snprintf(who, sizeof who, "%s (slave %u, %s)", p.config.name.c_str(), p.config.slave, p.config.profile.name.c_str());
  FixedString<96> text;
  if (ok) {
    fb.ok_ns = monotonic_ns();
    device_ok(who, s.fail_streak, s.reported);
    if (fb.fault_code != s.last_fault) {
      if (fb.fault_code != 0) {
        post(true, std::string(who) + ": drive fault " + std::to_string(fb.fault_code) + ": " +
                       p.config.profile.fault_text(fb.fault_code));
      } else {
        post(false, std::string(who) + ": drive fault cleared");
      }
      s.last_fault = fb.fault_code;
    }
    if (fb.fault_code != 0) text.assign(p.config.profile.fault_text(fb.fault_code));
  } else {
    device_failed(who, s.fail_streak, s.retry_at_ns, now, s.reported);
    text.assign("no communication: " + last_error_);
  }
  s.fb = fb;
  p.feedback.write(fb);
  p.fault_text.write(text);
  return now + p.config.poll_ns;
}

int64_t Link::poll_io(IoPort& p, IoState& s, int64_t now) {
  modbus_set_slave(ctx_, p.config.slave);
  IoOutputs out;
  p.outputs.try_read(out);
  int64_t next = now + 1'000'000'000;
  bool ok = true;
  bool any = false;
  for (std::size_t m = 0; m < p.config.maps.size() && ok; ++m) {
    const IoMap& map = p.config.maps[m];
    if (now < s.next_ns[m]) {
      next = std::min(next, s.next_ns[m]);
      continue;
    }
    any = true;
    const int64_t t0 = monotonic_ns();
    uint8_t bits[125];
    uint16_t regs[125];
    int rc = 0;
    switch (map.kind) {
      case IoKind::Coil:
        for (uint16_t i = 0; i < map.count; ++i) bits[i] = out.value[map.first_value + i] != 0 ? 1 : 0;
        rc = modbus_write_bits(ctx_, map.start, map.count, bits);
        break;
      case IoKind::HoldingRegister:
        for (uint16_t i = 0; i < map.count; ++i) {
          const double raw = std::round((out.value[map.first_value + i] - map.offset) / map.scale);
          regs[i] = map.is_signed ? static_cast<uint16_t>(static_cast<int16_t>(std::clamp(raw, -32768.0, 32767.0)))
                                  : static_cast<uint16_t>(std::clamp(raw, 0.0, 65535.0));
        }
        rc = modbus_write_registers(ctx_, map.start, map.count, regs);
        break;
      case IoKind::DiscreteInput: rc = modbus_read_input_bits(ctx_, map.start, map.count, bits); break;
      case IoKind::InputRegister: rc = modbus_read_input_registers(ctx_, map.start, map.count, regs); break;
    }
    ok = account(p.counters, rc, t0, map.is_output() ? "writing" : "reading", map.start);
    if (!ok) break;
    if (map.kind == IoKind::DiscreteInput) {
      for (uint16_t i = 0; i < map.count; ++i) s.in.value[map.first_value + i] = bits[i] ? 1 : 0;
    } else if (map.kind == IoKind::InputRegister) {
      for (uint16_t i = 0; i < map.count; ++i) {
        const double raw = map.is_signed ? static_cast<double>(static_cast<int16_t>(regs[i])) : static_cast<double>(regs[i]);
        s.in.value[map.first_value + i] = raw * map.scale + map.offset;
      }
    }
    s.in.map_ns[m] = monotonic_ns();
    s.next_ns[m] = now + map.poll_ns;
    next = std::min(next, s.next_ns[m]);
  }
  char who[96];
  std::snprintf(who, sizeof who, "%s (slave %u, I/O)", p.config.name.c_str(), p.config.slave);
  if (ok) {
    if (any) device_ok(who, s.fail_streak, s.reported);
    p.inputs.write(s.in);
  } else {
    device_failed(who, s.fail_streak, s.retry_at_ns, now, s.reported);
    next = now;  // the retry time decides
  }
  return next;
}

void Link::run() {
  while (!stop_.load(std::memory_order_relaxed)) {
    const int64_t now = monotonic_ns();
    const uint32_t stop_req = stop_drives_request_.load();
    if (!counters_.connected.load(std::memory_order_relaxed)) {
      if (now >= next_connect_ns_ && connect(now)) continue;
      if (stop_req != stop_drives_done_.load()) {
        stop_drives_ok_.store(false);
        stop_drives_done_.store(stop_req);
      }
      sleep_until(std::min(next_connect_ns_, now + kIdleNs));
      continue;
    }
    if (stop_req != stop_drives_done_.load()) {
      bool all = true;
      for (std::size_t i = 0; i < vfds_.size(); ++i) {
        VfdCommand stop_cmd;
        VfdPort& p = *vfds_[i];
        modbus_set_slave(ctx_, p.config.slave);
        VfdFeedback fb = vfd_state_[i].fb;
        VfdState& s = vfd_state_[i];
        s.written = false;
        stop_cmd.reset_count = s.reset_seen;
        all = (p.config.profile.protocol == Protocol::Huanyang ? exchange_huanyang(p, s, stop_cmd, fb)
                                                                : exchange_vfd(p, s, stop_cmd, fb)) && all;
      }
      stop_drives_ok_.store(all);
      stop_drives_done_.store(stop_req);
    }
    int64_t next = now + kIdleNs;
    last_result_ = Result::Ok;
    for (std::size_t i = 0; i < vfds_.size(); ++i) {
      VfdState& s = vfd_state_[i];
      if (now >= s.next_poll_ns && now >= s.retry_at_ns) s.next_poll_ns = poll_vfd(*vfds_[i], s, now);
      next = std::min(next, std::max(s.next_poll_ns, s.retry_at_ns));
    }
    for (std::size_t i = 0; i < ios_.size(); ++i) {
      IoState& s = io_state_[i];
      int64_t due = s.retry_at_ns;
      if (now >= s.retry_at_ns) due = std::max(poll_io(*ios_[i], s, now), s.retry_at_ns);
      next = std::min(next, due);
    }
    counters_.cycles.fetch_add(1, std::memory_order_relaxed);
    const bool silent = config_.transport == Transport::Tcp && timeouts_in_row_ >= kTimeoutsBeforeReconnect;
    if (last_result_ == Result::Broken || silent) {
      post(true, "connection lost (" + config_.describe() + "): " + last_error_ + "; reconnecting");
      connect_reported_ = true;
      disconnect();
      next_connect_ns_ = monotonic_ns() + backoff_ns_;
      continue;
    }
    if (next > now) sleep_until(next);
  }
  disconnect();
}

}  // namespace cnc::modbus
