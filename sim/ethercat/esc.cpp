#include "sim/ethercat/esc.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace cnc::ethercat::sim {
namespace {

// Bytes the master may write (others are read-only and keep their value).
bool writable(uint16_t a) noexcept {
  if (a >= reg::kProcessRam) return true;
  if (a >= 0x0010 && a <= 0x0013) return true;
  if (a >= 0x0100 && a <= 0x0103) return true;
  if (a >= 0x0120 && a <= 0x0121) return true;
  if (a >= 0x0200 && a <= 0x0203) return true;
  if (a >= 0x0300 && a <= 0x0313) return true;
  if (a >= 0x0400 && a <= 0x0401) return true;
  if (a >= 0x0420 && a <= 0x0421) return true;
  if (a >= 0x0500 && a <= 0x0507) return true;
  if (a >= 0x0600 && a <= 0x06FF) return true;
  if (a >= 0x0800 && a <= 0x087F) return ((a - 0x0800) % 8) != 5;  // SM status bytes are read-only
  if (a >= 0x0900 && a <= 0x0903) return true;                     // receive-time latch
  if (a >= 0x0910 && a <= 0x0917) return true;
  if (a >= 0x0920 && a <= 0x092B) return true;
  if (a >= 0x0930 && a <= 0x0935) return true;
  if (a >= 0x0980 && a <= 0x0981) return true;
  if (a >= 0x0990 && a <= 0x0997) return true;
  if (a >= 0x09A0 && a <= 0x09A7) return true;
  return false;
}

}  // namespace

Esc::Esc(EscConfig config, SlaveApplication* app, int64_t now_ns) : cfg_(std::move(config)), app_(app) {
  uint8_t* m = mem_.data();
  m[0x0000] = 0x11;  // ESC type (ET1100-like)
  m[0x0001] = 0x02;
  put16(m + 0x0002, 0x0001);
  m[reg::kFmmuCount] = kFmmus;
  m[reg::kSmCount] = kSms;
  m[0x0006] = 8;                       // RAM size, KB
  m[reg::kPortDescriptor] = 0x0F;      // ports 0 and 1: MII
  put16(m + reg::kFeatures, cfg_.dc ? 0x000C : 0x0000);
  if (cfg_.sii.size() >= 10) put16(m + reg::kStationAlias, get16(cfg_.sii.data() + 8));
  put16(m + reg::kWatchdogDivider, kWatchdogDivider100us);  // 100 us
  put16(m + reg::kWatchdogPd, 1000);       // 100 ms
  put16(m + reg::kWatchdogStatus, 1);
  put16(m + reg::kSiiControl, sii::kRead8);
  anchor_t_ = now_ns;
  anchor_local_ = cfg_.clock_at_power_on_ns;
  set_al_status();
}

int64_t Esc::local_time(int64_t t) const noexcept {
  const double rate = 1.0 + cfg_.drift_ppm * 1e-6 + correction_;
  return anchor_local_ + static_cast<int64_t>(std::llround(static_cast<double>(t - anchor_t_) * rate));
}

int64_t Esc::system_time(int64_t t) const noexcept {
  return local_time(t) + static_cast<int64_t>(get64(mem_.data() + reg::kDcSystemOffset));
}

void Esc::rate_anchor(int64_t t) noexcept {
  anchor_local_ = local_time(t);
  anchor_t_ = t;
}

void Esc::set_al_status() noexcept {
  put16(mem_.data() + reg::kAlStatus, static_cast<uint16_t>(static_cast<uint8_t>(state_) | (error_ ? kAlErrorFlag : 0)));
}

void Esc::enter(AlState s, int64_t now) noexcept {
  const AlState from = state_;
  state_ = s;
  if (s == AlState::Init) {
    mq_count_ = 0;
    sm1_full_ = false;
    mem_[reg::kSm0 + 8 + 5] = 0;
  }
  if (s != AlState::Op && s != AlState::SafeOp) outputs_valid_ = false;
  if (s == AlState::SafeOp && from == AlState::PreOp) outputs_valid_ = false;
  set_al_status();
  app_->on_state(from, s, now);
}

void Esc::set_error(AlState to, uint16_t code, int64_t now_ns) noexcept {
  error_ = true;
  put16(mem_.data() + reg::kAlStatusCode, code);
  if (static_cast<uint8_t>(to) < static_cast<uint8_t>(state_)) enter(to, now_ns);
  set_al_status();
}

void Esc::al_request(uint8_t value, int64_t now) noexcept {
  const uint8_t req = value & 0x0F;
  const bool ack = (value & kAlErrorFlag) != 0;
  if (error_) {
    if (!ack) return;  // an indicated error must be acknowledged first
    error_ = false;
    put16(mem_.data() + reg::kAlStatusCode, 0);
    set_al_status();
  }
  const auto to = static_cast<AlState>(req);
  if (to == state_) return;
  auto refuse = [&](uint16_t code) {
    error_ = true;
    put16(mem_.data() + reg::kAlStatusCode, code);
    set_al_status();
  };
  if (req != 1 && req != 2 && req != 3 && req != 4 && req != 8) return refuse(al::kUnknownState);
  if (to == AlState::Boot) return refuse(al::kBootNotSupported);
  const auto rank = [](AlState s) { return static_cast<uint8_t>(s); };
  const bool down = rank(to) < rank(state_);
  if (!down) {
    const bool valid = (state_ == AlState::Init && to == AlState::PreOp) ||
                       (state_ == AlState::PreOp && to == AlState::SafeOp) ||
                       (state_ == AlState::SafeOp && to == AlState::Op);
    if (!valid) return refuse(al::kInvalidStateChange);
  }
  if (refuse_state_ == to && refuse_code_ != 0) return refuse(refuse_code_);
  if (!down && to == AlState::PreOp) {
    const SmEntry s0 = sm(0), s1 = sm(1);
    const bool ok = s0.enabled() && s0.start == cfg_.mailbox_out_start && s0.length == cfg_.mailbox_out_size &&
                    (s0.control & 0x0F) == 0x06 && s1.enabled() && s1.start == cfg_.mailbox_in_start &&
                    s1.length == cfg_.mailbox_in_size && (s1.control & 0x0F) == 0x02;
    if (!ok) return refuse(al::kInvalidMailboxPreop);
  }
  if (!down && to == AlState::Op && !outputs_valid_) return refuse(al::kNoValidOutputs);
  if (!down) {
    if (const uint16_t code = app_->check_transition(state_, to, *this)) return refuse(code);
  }
  enter(to, now);
}

void Esc::sii_command() noexcept {
  const uint16_t ctl = get16(mem_.data() + reg::kSiiControl);
  uint16_t status = sii::kRead8;
  if (ctl & sii::kRead) {
    const uint32_t word = get32(mem_.data() + reg::kSiiAddress);
    const std::size_t byte = std::size_t{word} * 2;
    if (byte >= cfg_.sii.size()) {
      status |= sii::kError;
      std::memset(mem_.data() + reg::kSiiData, 0xFF, 8);
    } else {
      for (std::size_t i = 0; i < 8; ++i) {
        mem_[reg::kSiiData + i] = byte + i < cfg_.sii.size() ? cfg_.sii[byte + i] : 0xFF;
      }
    }
  } else if (ctl & sii::kWrite) {
    status |= sii::kError;  // the simulated EEPROM is read-only
  }
  put16(mem_.data() + reg::kSiiControl, status);
}

void Esc::drift_control(uint64_t received, unsigned bytes, int64_t t) noexcept {
  const int64_t delay = get32(mem_.data() + reg::kDcSystemDelay);
  const int64_t own = system_time(t);
  int64_t diff;
  if (bytes >= 8) diff = own - static_cast<int64_t>(received) - delay;
  else diff = static_cast<int32_t>(static_cast<uint32_t>(own) - static_cast<uint32_t>(received + delay));
  last_diff_ns_ = diff;
  rate_anchor(t);
  // The ESC's time control loop: a filtered step and a speed correction.
  anchor_local_ -= std::clamp<int64_t>(diff / 8, -1'000'000, 1'000'000);
  correction_ = std::clamp(correction_ - static_cast<double>(diff) * 2e-9, -5e-4, 5e-4);
}

void Esc::refill_mailbox() noexcept {
  if (sm1_full_ || mq_count_ == 0) return;
  const SmEntry s1 = sm(1);
  if (!s1.enabled() || s1.start + s1.length > kMemory) return;
  const Pending& m = mailbox_queue_[mq_head_];
  std::memset(mem_.data() + s1.start, 0, s1.length);
  std::memcpy(mem_.data() + s1.start, m.data.data(), std::min<std::size_t>(m.size, s1.length));
  mq_head_ = (mq_head_ + 1) % mailbox_queue_.size();
  --mq_count_;
  sm1_full_ = true;
  mem_[reg::kSm0 + 8 + 5] = sm::kStatusFull;
}

void Esc::post_mailbox(const uint8_t* data, std::size_t size) noexcept {
  if (mq_count_ == mailbox_queue_.size()) {
    ++mailbox_overflows_;
    return;
  }
  Pending& p = mailbox_queue_[(mq_head_ + mq_count_) % mailbox_queue_.size()];
  p.size = std::min(size, p.data.size());
  std::memcpy(p.data.data(), data, p.size);
  ++mq_count_;
  refill_mailbox();
}

bool Esc::read(uint16_t addr, uint16_t len, uint8_t* out, bool or_mode, int64_t t) noexcept {
  if (std::size_t{addr} + len > kMemory) return false;
  uint8_t* m = mem_.data();
  if (overlaps(addr, len, reg::kDcSystemTime, 8)) put64(m + reg::kDcSystemTime, static_cast<uint64_t>(system_time(t)));
  if (overlaps(addr, len, reg::kDcSystemDiff, 4)) {
    const int64_t d = last_diff_ns_;
    const uint32_t mag = static_cast<uint32_t>(std::min<int64_t>(d < 0 ? -d : d, 0x7FFFFFFF));
    put32(m + reg::kDcSystemDiff, mag | (d < 0 ? 0x80000000u : 0u));
  }
  if (overlaps(addr, len, reg::kDcSync0Status, 1)) m[reg::kDcSync0Status] = sync0_active() ? 1 : 0;
  put16(m + reg::kDlStatus, static_cast<uint16_t>(0x0010 | 0x0200 | (port1_open_ ? 0x0820 : 0x0400)));
  const SmEntry s1 = sm(1);
  const bool touches_mailbox_in = s1.enabled() && overlaps(addr, len, s1.start, s1.length);
  if (touches_mailbox_in && !sm1_full_) return false;  // empty mailbox: not read, no WKC
  const SmEntry s3 = sm(3);
  if (s3.enabled() && s3.length > 0 && overlaps(addr, len, s3.start, s3.length) && s3.start + s3.length <= kMemory) {
    app_->fill_inputs(m + s3.start, s3.length);
  }
  if (or_mode) {
    for (uint16_t i = 0; i < len; ++i) out[i] |= m[addr + i];
  } else {
    std::memcpy(out, m + addr, len);
  }
  if (touches_mailbox_in && addr + len >= s1.start + s1.length) {
    sm1_full_ = false;
    m[reg::kSm0 + 8 + 5] = 0;
    refill_mailbox();
  }
  return true;
}

bool Esc::write(uint16_t addr, uint16_t len, const uint8_t* in, int64_t t_fwd, int64_t t_ret, bool port1) noexcept {
  if (std::size_t{addr} + len > kMemory) return false;
  uint8_t* m = mem_.data();
  if (addr >= reg::kProcessRam) {
    std::memcpy(m + addr, in, len);
  } else {
    for (uint16_t i = 0; i < len; ++i) {
      const uint16_t a = static_cast<uint16_t>(addr + i);
      if (writable(a)) m[a] = in[i];
    }
  }
  after_write(addr, len, t_fwd, t_ret, port1);
  return true;
}

void Esc::after_write(uint16_t addr, uint16_t len, int64_t t_fwd, int64_t t_ret, bool port1) noexcept {
  uint8_t* m = mem_.data();
  if (overlaps(addr, len, reg::kAlControl, 1)) al_request(m[reg::kAlControl], t_fwd);
  if (overlaps(addr, len, reg::kSiiControl, 2)) sii_command();
  if (overlaps(addr, len, reg::kRxErrors, 0x14)) std::memset(m + reg::kRxErrors, 0, 0x14);
  if (overlaps(addr, len, reg::kDcPortTime0, 4) && cfg_.dc) {
    put32(m + reg::kDcPortTime0, static_cast<uint32_t>(local_time(t_fwd)));
    put32(m + reg::kDcPortTime0 + 4, port1 ? static_cast<uint32_t>(local_time(t_ret)) : 0);
    put64(m + reg::kDcReceiveTimePu, static_cast<uint64_t>(local_time(t_fwd)));
  }
  if (overlaps(addr, len, reg::kDcSystemTime, 8) && cfg_.dc && addr >= reg::kDcSystemTime) {
    const unsigned bytes = len >= 8 ? 8 : 4;
    drift_control(bytes == 8 ? get64(m + reg::kDcSystemTime) : get32(m + reg::kDcSystemTime), bytes, t_fwd);
  }
  if (overlaps(addr, len, reg::kDcActivation, 1) && cfg_.dc) {
    // Cyclic operation with SYNC0: pulses from the start time on, every cycle.
    const bool on = sync0_active() && sync0_cycle_ns() > 0;
    sync0_next_ = on ? static_cast<int64_t>(get64(m + reg::kDcStartTime)) : -1;
  }
  if (overlaps(addr, len, reg::kSm0, 8 * kSms)) {
    m[reg::kSm0 + 8 + 5] = sm1_full_ ? sm::kStatusFull : 0;
    if (!sm(1).enabled()) {
      sm1_full_ = false;
      m[reg::kSm0 + 8 + 5] = 0;
    } else {
      refill_mailbox();
    }
  }
  const SmEntry s0 = sm(0);
  if (s0.enabled() && s0.length > 0 && overlaps(addr, len, s0.start, s0.length) && addr + len >= s0.start + s0.length &&
      state_ != AlState::Init) {
    app_->on_mailbox(m + s0.start, s0.length, *this, t_fwd);
  }
  const SmEntry s2 = sm(2);
  if (s2.enabled() && s2.length > 0 && overlaps(addr, len, s2.start, s2.length) && addr + len >= s2.start + s2.length &&
      s2.start + s2.length <= kMemory) {
    last_outputs_ns_ = t_fwd;
    ++outputs_count_;
    if (state_ == AlState::SafeOp || state_ == AlState::Op) {
      outputs_valid_ = true;
      put16(m + reg::kWatchdogStatus, 1);
    }
    app_->on_outputs(m + s2.start, s2.length, t_fwd);
  }
  (void)t_ret;
}

int64_t Esc::watchdog_ns() const noexcept {
  return ethercat::watchdog_ns(get16(mem_.data() + reg::kWatchdogDivider), get16(mem_.data() + reg::kWatchdogPd));
}

void Esc::run_sync0(int64_t now_ns) noexcept {
  if (sync0_next_ < 0) return;
  const int64_t cycle = sync0_cycle_ns();
  const int64_t st = system_time(now_ns);
  if (st - sync0_next_ > 100 * cycle) sync0_next_ += (st - sync0_next_) / cycle * cycle;  // long pause: no burst
  while (st >= sync0_next_) {
    ++sync0_pulses_;
    app_->on_sync0(now_ns - (st - sync0_next_));
    sync0_next_ += cycle;
  }
}

void Esc::poll(int64_t now_ns) noexcept {
  run_sync0(now_ns);
  // The process-data watchdog (SM2 with its watchdog trigger bit, time
  // from 0x0400/0x0420, 0 = off): outputs that stop arriving expire it.
  // The application reacts first (its safe state, with the watchdog as the
  // reason), then the slave drops to SAFEOP with 0x001B.
  if (state_ == AlState::Op && outputs_valid_ && (sm(2).control & sm::kWatchdogTrigger) && watchdog_ns() > 0 &&
      now_ns - last_outputs_ns_ > watchdog_ns()) {
    ++wd_expired_;
    outputs_valid_ = false;
    put16(mem_.data() + reg::kWatchdogStatus, 0);
    put16(mem_.data() + reg::kWatchdogCounter, static_cast<uint16_t>(get16(mem_.data() + reg::kWatchdogCounter) + 1));
    app_->on_watchdog(now_ns);
    set_error(AlState::SafeOp, al::kSmWatchdog, now_ns);
  }
  app_->poll(now_ns);
}

uint16_t Esc::execute(DatagramRef& d, bool addressed_read_only, int64_t t_fwd, int64_t t_ret, bool port1_open) noexcept {
  port1_open_ = port1_open;  // for DL status
  poll(t_fwd);
  const uint16_t ado = d.ado();
  const uint16_t len = d.length();
  uint8_t* data = d.data();
  switch (d.command()) {
    case Command::APRD: case Command::FPRD:
      return read(ado, len, data, false, t_fwd) ? 1 : 0;
    case Command::BRD:
      return read(ado, len, data, true, t_fwd) ? 1 : 0;
    case Command::APWR: case Command::FPWR: case Command::BWR:
      return write(ado, len, data, t_fwd, t_ret, port1_open) ? 1 : 0;
    case Command::APRW: case Command::FPRW: case Command::BRW: {
      uint8_t tmp[kMaxDatagramData];
      std::memcpy(tmp, data, len);
      uint16_t w = read(ado, len, data, false, t_fwd) ? 1 : 0;
      if (write(ado, len, tmp, t_fwd, t_ret, port1_open)) w = static_cast<uint16_t>(w + 2);
      return w;
    }
    case Command::ARMW: case Command::FRMW:
      if (addressed_read_only) return read(ado, len, data, false, t_fwd) ? 1 : 0;
      return write(ado, len, data, t_fwd, t_ret, port1_open) ? 1 : 0;
    default:
      return 0;
  }
}

uint16_t Esc::execute_logical(DatagramRef& d, int64_t now_ns) noexcept {
  poll(now_ns);
  const Command c = d.command();
  const uint32_t a = d.address();
  const uint32_t len = d.length();
  bool read_hit = false, write_hit = false;
  for (unsigned n = 0; n < kFmmus; ++n) {
    const FmmuEntry f = fmmu(n);
    if (!(f.activate & 1) || f.length == 0) continue;
    const uint32_t lo = std::max(a, f.logical_start);
    const uint32_t hi = std::min(a + len, f.logical_start + f.length);
    if (lo >= hi) continue;
    const auto phys = static_cast<uint16_t>(f.physical_start + (lo - f.logical_start));
    const auto count = static_cast<uint16_t>(hi - lo);
    uint8_t* frame = d.data() + (lo - a);
    if ((f.type & 1) && (c == Command::LRD || c == Command::LRW)) {
      if (read(phys, count, frame, false, now_ns)) read_hit = true;
    }
    if ((f.type & 2) && (c == Command::LWR || c == Command::LRW)) {
      if (write(phys, count, frame, now_ns, now_ns, true)) write_hit = true;
    }
  }
  if (c == Command::LRD) return read_hit ? 1 : 0;
  if (c == Command::LWR) return write_hit ? 1 : 0;
  return static_cast<uint16_t>((read_hit ? 1 : 0) + (write_hit ? 2 : 0));
}

void Esc::inject_invalid_frames(unsigned port, unsigned n) noexcept {
  if (port > 3) return;
  uint8_t& c = mem_[reg::kRxErrors + 2 * port];
  c = static_cast<uint8_t>(std::min<unsigned>(255, c + n));
}

void Esc::inject_lost_link(unsigned port) noexcept {
  if (port > 3) return;
  uint8_t& c = mem_[reg::kRxErrors + 0x10 + port];
  c = static_cast<uint8_t>(std::min<unsigned>(255, c + 1u));
}

}  // namespace cnc::ethercat::sim
