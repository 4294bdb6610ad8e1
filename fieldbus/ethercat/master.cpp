#include "fieldbus/ethercat/master.hpp"

#include <time.h>

#include <algorithm>
#include <cstdarg>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <future>

#include "core/util/messages.hpp"
#include "cia402/error_codes.hpp"
#include "fieldbus/canopen/sdo_abort.hpp"
#ifdef CNC_ETHERCAT_ESI
#include "fieldbus/ethercat/esi.hpp"
#endif

namespace cnc::ethercat {
namespace {

int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return int64_t{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
}
void sleep_ns(int64_t ns) {
  timespec ts{static_cast<time_t>(ns / 1'000'000'000), static_cast<long>(ns % 1'000'000'000)};
  nanosleep(&ts, nullptr);
}
std::string fmt(const char* f, ...) __attribute__((format(printf, 1, 2)));
std::string fmt(const char* f, ...) {
  char b[512];
  va_list ap;
  va_start(ap, f);
  std::vsnprintf(b, sizeof b, f, ap);
  va_end(ap);
  return b;
}
std::string object(uint16_t index, uint8_t sub) { return fmt("0x%04X:%02X", index, sub); }
std::string value_text(const std::vector<uint8_t>& d) {
  if (d.size() <= 8) {
    uint64_t v = 0;
    for (std::size_t i = 0; i < d.size(); ++i) v |= uint64_t{d[i]} << (8 * i);
    return fmt("0x%0*" PRIX64, static_cast<int>(d.size() * 2), v);
  }
  return fmt("%zu bytes", d.size());
}
std::vector<uint8_t> le(uint64_t v, unsigned n) {
  std::vector<uint8_t> d(n);
  for (unsigned i = 0; i < n; ++i) d[i] = static_cast<uint8_t>(v >> (8 * i));
  return d;
}
std::string abort_text(uint32_t code) {
  return fmt("aborted by the slave: 0x%08X %s", code, canopen::sdo_abort_text(code));
}

}  // namespace

Master::Master(MasterConfig config, MessageQueue* messages) : cfg_(std::move(config)), messages_(messages) {}

Master::Master(MasterConfig config, MessageQueue* messages, std::unique_ptr<Link> cyclic, std::unique_ptr<Link> acyclic)
    : cfg_(std::move(config)), messages_(messages), cyclic_link_(std::move(cyclic)), acyclic_link_(std::move(acyclic)) {}

Master::~Master() { stop(); }

void Master::stop() {
  stop_.store(true);
  jobs_cv_.notify_all();
  if (worker_.joinable()) worker_.join();
  // Requests queued while the worker stopped still get their answer.
  for (;;) {
    std::function<void()> job;
    {
      std::lock_guard lock(jobs_mutex_);
      if (jobs_.empty()) break;
      job = std::move(jobs_.front());
      jobs_.pop_front();
    }
    job();
  }
}

void Master::release() {
  stop();
  if (!acyclic_link_ || phase() == BusPhase::Down) return;
  phase_.store(BusPhase::Down, std::memory_order_release);
  uint8_t init[2] = {0x01, 0};
  (void)transact(Command::BWR, physical_address(0, reg::kAlControl), init, 2);
}

void Master::drain(Link& link) noexcept {
  uint8_t buf[kMaxFrame];
  for (int i = 0; i < 100000 && link.receive(buf, 0) > 0; ++i) {
  }
}

void Master::fail(const std::string& what) const { throw StartupError(cfg_.name + ": start-up stopped: " + what); }
void Master::fail_slave(const SlaveInfo& s, const std::string& what) const { fail(slave_label(s.position) + ": " + what); }

std::string Master::slave_label(unsigned position) const {
  std::string name;
  if (const SlaveConfig* c = cfg_.slave(position); c && !c->name.empty()) name = c->name;
  else if (position >= 1 && position <= slaves_.size()) name = slaves_[position - 1].name;
  return name.empty() ? fmt("slave %u", position) : fmt("slave %u (%s)", position, name.c_str());
}

void Master::post(bool error, const std::string& text) {
  if (messages_) messages_->post(error ? MessageKind::Error : MessageKind::Text, cfg_.name, text);
  else std::fprintf(stderr, "%s: %s\n", cfg_.name.c_str(), text.c_str());
}

// ---------------------------------------------------------------- datagrams

std::optional<uint16_t> Master::transact(Command c, uint32_t address, uint8_t* data, uint16_t length) {
  uint8_t frame[kMaxFrame];
  uint8_t reply[kMaxFrame];
  for (int attempt = 0; attempt < 3; ++attempt) {
    const uint8_t idx = acyclic_index_;
    acyclic_index_ = static_cast<uint8_t>(acyclic_index_ == 0xFF ? 0x80 : acyclic_index_ + 1);
    FrameBuilder fb;
    fb.begin(frame, acyclic_link_->mac());
    if (!fb.add(c, idx, address, length, data)) return std::nullopt;
    const std::size_t n = fb.finish();
    if (!acyclic_link_->send(frame, n)) {
      sleep_ns(1'000'000);
      continue;
    }
    const int64_t deadline = monotonic_ns() + 50'000'000;
    for (;;) {
      const int64_t left = deadline - monotonic_ns();
      if (left <= 0) break;
      const std::size_t m = acyclic_link_->receive(reply, left);
      if (m == 0) {
        if (acyclic_link_->name().rfind("sim:", 0) == 0) break;  // in-process: no reply means lost
        continue;
      }
      FrameView v;
      if (parse_frame(reply, m, v) != ParseResult::Ok) continue;
      const DatagramRef& d = v.datagrams[0];
      if (d.index() != idx || d.command() != c || d.length() != length) continue;
      std::memcpy(data, d.data(), length);
      return d.wkc();
    }
  }
  return std::nullopt;
}

uint16_t Master::fprd(const SlaveInfo& s, uint16_t ado, uint8_t* data, uint16_t len) {
  return transact(Command::FPRD, physical_address(s.station, ado), data, len).value_or(0);
}
uint16_t Master::fpwr(const SlaveInfo& s, uint16_t ado, const uint8_t* data, uint16_t len) {
  uint8_t tmp[kMaxDatagramData];
  std::memcpy(tmp, data, len);
  return transact(Command::FPWR, physical_address(s.station, ado), tmp, len).value_or(0);
}
void Master::must_write(const SlaveInfo& s, uint16_t ado, const uint8_t* data, uint16_t len, const char* what) {
  if (fpwr(s, ado, data, len) != 1) fail_slave(s, fmt("writing %s (register 0x%04X) got no answer", what, ado));
}

SlaveInfo* Master::find(unsigned position) {
  return position >= 1 && position <= slaves_.size() ? &slaves_[position - 1] : nullptr;
}

// ---------------------------------------------------------------- scan

std::vector<uint8_t> Master::read_sii(const SlaveInfo& s) {
  uint8_t owner[2] = {0, 0};
  must_write(s, reg::kSiiOwner, owner, 2, "SII owner");
  std::vector<uint8_t> image;
  uint32_t word = 0;
  while (image.size() < 8192) {
    uint8_t cmd[6];
    put16(cmd, sii::kRead);
    put32(cmd + 2, word);
    must_write(s, reg::kSiiControl, cmd, 6, "SII read command");
    uint8_t st[2] = {};
    int polls = 0;
    do {
      if (fprd(s, reg::kSiiControl, st, 2) != 1) fail_slave(s, "SII status got no answer");
    } while ((get16(st) & sii::kBusy) && ++polls < 1000);
    if (get16(st) & (sii::kError | sii::kBusy)) {
      fail_slave(s, fmt("reading SII word 0x%04X failed: status 0x%04X%s", word, get16(st),
                        (get16(st) & sii::kBusy) ? " (busy)" : " (EEPROM error)"));
    }
    const uint16_t n = (get16(st) & sii::kRead8) ? 8 : 4;
    uint8_t data[8] = {};
    if (fprd(s, reg::kSiiData, data, n) != 1) fail_slave(s, "SII data got no answer");
    image.insert(image.end(), data, data + n);
    word += n / 2;
    const std::size_t known = sii_length_known(image);
    if (known > 0 && image.size() >= known) {
      image.resize(known);
      break;
    }
  }
  return image;
}

void Master::scan() {
  if (!cyclic_link_) cyclic_link_ = open_link(cfg_.interface);
  if (!acyclic_link_) acyclic_link_ = open_link(cfg_.interface);
  uint8_t b[2] = {};
  const auto count = transact(Command::BRD, 0, b, 2);
  if (!count) fail("no frame came back on " + acyclic_link_->name() + " (cable, interface up, slaves powered?)");
  if (*count == 0) fail("no slave answers on " + acyclic_link_->name());
  const unsigned n = *count;
  for (const SlaveConfig& c : cfg_.slaves) {
    if (c.position > n) {
      fail(fmt("configured slave %u%s%s%s is missing: only %u slave%s answer%s on %s", c.position,
               c.name.empty() ? "" : " (", c.name.c_str(), c.name.empty() ? "" : ")", n, n == 1 ? "" : "s",
               n == 1 ? "s" : "", acyclic_link_->name().c_str()));
    }
  }
  // Every slave to INIT (acknowledging errors), FMMUs, SMs and SYNC off.
  uint8_t init[2] = {0x11, 0};
  (void)transact(Command::BWR, physical_address(0, reg::kAlControl), init, 2);
  uint8_t zeros[256] = {};
  (void)transact(Command::BWR, physical_address(0, reg::kFmmu0), zeros, 128);
  (void)transact(Command::BWR, physical_address(0, reg::kSm0), zeros, 64);
  (void)transact(Command::BWR, physical_address(0, reg::kDcActivation), zeros, 1);
  (void)transact(Command::BWR, physical_address(0, reg::kRxErrors), zeros, 8);

  if (state_ && n != slaves_.size()) {
    // A rescan (restart): the drives hold slots into the image, the HAL reads the states.
    fail(fmt("restart: %u slaves answer, %zu were configured before", n, slaves_.size()));
  }
  scanned_ = true;
  if (!state_) {
    slaves_.assign(n, SlaveInfo{});
    state_ = std::make_unique<SlaveState[]>(n);
  } else {
    for (SlaveInfo& s : slaves_) s = SlaveInfo{};
  }
  for (unsigned p = 1; p <= n; ++p) {
    SlaveInfo& s = slaves_[p - 1];
    s.position = p;
    s.station = static_cast<uint16_t>(0x1000 + p);
    uint8_t st[2];
    put16(st, s.station);
    const auto w = transact(Command::APWR, physical_address(auto_increment_address(p - 1), reg::kStationAddress), st, 2);
    if (!w || *w != 1) fail(fmt("slave %u did not take its station address 0x%04X", p, s.station));
  }
  for (SlaveInfo& s : slaves_) {
    uint8_t id[10] = {};
    if (fprd(s, reg::kType, id, 10) != 1) fail_slave(s, "does not answer at its station address");
    s.features = get16(id + 8);
    s.has_dc = (s.features & 0x0004) != 0;
    uint8_t dl[2] = {};
    (void)fprd(s, reg::kDlStatus, dl, 2);
    s.port1_open = (get16(dl) & 0x0800) != 0;
    const std::vector<uint8_t> image = read_sii(s);
    try {
      s.sii = parse_sii(image);
    } catch (const std::exception& e) {
      fail_slave(s, std::string("SII EEPROM: ") + e.what());
    }
    if (!s.sii.checksum_ok) fail_slave(s, "SII EEPROM: checksum of the configuration area is wrong");
    const SlaveConfig* c = cfg_.slave(s.position);
    s.name = c && !c->name.empty() ? c->name : s.sii.name;
    if (c) {
      auto check = [&](const char* what, std::optional<uint32_t> want, uint32_t have) {
        if (want && *want != have) {
          fail_slave(s, fmt("identity: %s is 0x%08X, expected 0x%08X (wrong device at this position?)", what, have, *want));
        }
      };
      check("vendor ID", c->vendor_id, s.sii.vendor_id);
      check("product code", c->product_code, s.sii.product_code);
      check("revision", c->revision, s.sii.revision);
    }
  }
}

// ---------------------------------------------------------------- AL states

void Master::request_state(SlaveInfo& s, AlState to) {
  uint8_t st[6] = {};
  (void)fprd(s, reg::kAlStatus, st, 6);
  const uint8_t from = st[0] & 0x0F;
  uint8_t req[2] = {static_cast<uint8_t>(to), 0};
  must_write(s, reg::kAlControl, req, 2, "AL control");
  const int64_t deadline = monotonic_ns() + cfg_.state_timeout_ms * 1'000'000;
  for (;;) {
    if (fprd(s, reg::kAlStatus, st, 6) != 1) fail_slave(s, "AL status got no answer");
    const uint8_t now = st[0] & 0x0F;
    state_[s.position - 1].al_state.store(now);
    if (st[0] & kAlErrorFlag) {
      const uint16_t code = get16(st + 4);
      state_[s.position - 1].al_code.store(code);
      uint8_t ack[2] = {static_cast<uint8_t>(now | kAlErrorFlag), 0};
      (void)fpwr(s, reg::kAlControl, ack, 2);
      fail_slave(s, fmt("%s -> %s refused: AL status code 0x%04X %s (slave stays in %s)", al_state_name(from),
                        al_state_name(static_cast<uint8_t>(to)), code, al_status_text(code), al_state_name(now)));
    }
    if (now == static_cast<uint8_t>(to)) return;
    if (monotonic_ns() > deadline) {
      fail_slave(s, fmt("%s -> %s: no state change within %lld ms (still %s)", al_state_name(from),
                        al_state_name(static_cast<uint8_t>(to)), static_cast<long long>(cfg_.state_timeout_ms),
                        al_state_name(now)));
    }
    sleep_ns(100'000);
  }
}

void Master::configure_mailbox(SlaveInfo& s) {
  uint8_t sms[16] = {};
  if (s.sii.mailbox_rx_size > 0 && s.sii.mailbox_tx_size > 0) {
    SmEntry{s.sii.mailbox_rx_offset, s.sii.mailbox_rx_size, sm::kMailboxOut, 0, 1, 0}.encode(sms);
    SmEntry{s.sii.mailbox_tx_offset, s.sii.mailbox_tx_size, sm::kMailboxIn, 0, 1, 0}.encode(sms + 8);
  }
  must_write(s, reg::kSm0, sms, 16, "SM0/SM1 (mailbox)");
}

// ---------------------------------------------------------------- CoE

void Master::check_sdo(SlaveInfo& s, uint16_t index, uint8_t sub, const std::vector<uint8_t>& data,
                       const std::string& why, bool ca) {
  const SdoResult r = do_download(s, index, sub, data, ca);
  if (!r.ok) {
    fail_slave(s, "writing " + object(index, sub) + " = " + value_text(data) + " (" + why + ") refused: " + r.error);
  }
  // Read back: a slave that takes a value and keeps another is found here,
  // not later as a strange machine.
  const SdoResult back = do_upload(s, index, sub, ca);
  if (!back.ok) fail_slave(s, "verification of " + object(index, sub) + " (" + why + "): reading back failed: " + back.error);
  std::vector<uint8_t> got = back.data;
  got.resize(std::max(got.size(), data.size()), 0);
  if (!std::equal(data.begin(), data.end(), got.begin()) ||
      std::any_of(got.begin() + static_cast<long>(data.size()), got.end(), [](uint8_t b) { return b != 0; })) {
    fail_slave(s, "verification of " + object(index, sub) + " (" + why + ") failed: the slave has " +
                      value_text(back.data) + " after " + value_text(data) + " was written");
  }
}

void Master::configure_coe(SlaveInfo& s) {
  const SlaveConfig* c = cfg_.slave(s.position);
  if (!s.sii.has_coe()) {
    if (c && (c->rx_pdo || c->tx_pdo || !c->sdos.empty())) {
      fail_slave(s, "has no CoE mailbox (SII mailbox protocols 0x" + fmt("%04X", s.sii.mailbox_protocols) +
                        "): its PDOs and SDOs cannot be configured");
    }
    return;
  }
  const uint16_t rx_index = c ? c->rx_pdo_index : 0x1600, tx_index = c ? c->tx_pdo_index : 0x1A00;
  const bool ca = c && c->complete_access && (s.sii.coe_details & 0x20);
  for (const bool out : {true, false}) {
    const auto& map = out ? s.rx : s.tx;
    const uint16_t assign = out ? 0x1C12 : 0x1C13;
    const uint16_t pdo = out ? rx_index : tx_index;
    const char* kind = out ? "RxPDO" : "TxPDO";
    if (ca) {  // complete access: count (16 bits) and every entry in one transfer
      std::vector<uint8_t> m{0, 0};
      check_sdo(s, assign, 0, {0, 0}, std::string(kind) + " assignment cleared (complete access)", true);
      m[0] = static_cast<uint8_t>(map.size());
      for (const auto& e : map) {
        const auto b = le(e.encode(), 4);
        m.insert(m.end(), b.begin(), b.end());
      }
      check_sdo(s, pdo, 0, m, std::string(kind) + " mapping (complete access)", true);
      if (!map.empty()) check_sdo(s, assign, 0, {1, 0, static_cast<uint8_t>(pdo), static_cast<uint8_t>(pdo >> 8)},
                                  std::string(kind) + " assignment (complete access)", true);
      continue;
    }
    check_sdo(s, assign, 0, le(0, 1), std::string(kind) + " assignment cleared");
    check_sdo(s, pdo, 0, le(0, 1), std::string(kind) + " mapping cleared");
    for (std::size_t k = 0; k < map.size(); ++k) {
      check_sdo(s, pdo, static_cast<uint8_t>(k + 1), le(map[k].encode(), 4),
                fmt("%s mapping entry %zu: %s, %u bits", kind, k + 1, object(map[k].index, map[k].sub).c_str(),
                    map[k].bits));
    }
    check_sdo(s, pdo, 0, le(map.size(), 1), std::string(kind) + " mapping count");
    if (!map.empty()) {
      check_sdo(s, assign, 1, le(pdo, 2), std::string(kind) + " assigned");
      check_sdo(s, assign, 0, le(1, 1), std::string(kind) + " assignment count");
    }
  }
  const bool sync0 = cfg_.dc && s.has_dc && (!c || c->sync0) && (s.assign_activate & 0x0200) != 0;
  check_sdo(s, 0x1C32, 1, le(sync0 ? 2 : 1, 2), sync0 ? "outputs synchronised to DC SYNC0" : "outputs synchronised to SM2");
  check_sdo(s, 0x1C32, 2, le(static_cast<uint64_t>(cfg_.cycle_ns), 4), "cycle time, ns");
  if (c) {
    for (const StartupSdo& sdo : c->sdos) check_sdo(s, sdo.index, sdo.sub, sdo.data, "value from " + sdo.origin);
  }
}

// ---------------------------------------------------------------- process data

void Master::layout_process_data() {
  uint32_t out = 0, in = 0;
  expected_wkc_ = 0;
  for (SlaveInfo& s : slaves_) {
    s.out_bits = 0;
    s.in_bits = 0;
    for (const auto& e : s.rx) s.out_bits += e.bits;
    for (const auto& e : s.tx) s.in_bits += e.bits;
    s.out_bit = out * 8;
    s.in_bit = in * 8;
    out += (s.out_bits + 7) / 8;
    in += (s.in_bits + 7) / 8;
    if (s.out_bits) expected_wkc_ = static_cast<uint16_t>(expected_wkc_ + 2);
    if (s.in_bits) expected_wkc_ = static_cast<uint16_t>(expected_wkc_ + 1);
  }
  if (out + in > kMaxDatagramData - 64) fail(fmt("process data of %u bytes does not fit one frame", out + in));
  // Same sizes (a restart): keep the buffers untouched, the drives write into them.
  if (outputs_.size() != out) outputs_.assign(out, 0);
  if (inputs_.size() != in) inputs_.assign(in, 0);
}

void Master::configure_process_data(SlaveInfo& s) {
  s.sm2_start = 0x1100;
  s.sm3_start = 0x1180;
  uint8_t c2 = sm::kOutputs, c3 = sm::kInputs;
  for (const SiiSm& m : s.sii.sms) {
    if (m.type == 3) s.sm2_start = m.start, c2 = m.control ? m.control : c2;
    if (m.type == 4) s.sm3_start = m.start, c3 = m.control ? m.control : c3;
  }
  const auto out_bytes = static_cast<uint16_t>((s.out_bits + 7) / 8), in_bytes = static_cast<uint16_t>((s.in_bits + 7) / 8);
  // The process-data watchdog: SM2's watchdog trigger bit follows the
  // configuration, whatever the SII/ESI control byte says (a device
  // description without it would leave the slave unwatched).
  const SlaveConfig* c = cfg_.slave(s.position);
  const uint32_t watchdog_ms = c ? c->watchdog_ms : cfg_.watchdog_ms;
  c2 = static_cast<uint8_t>(watchdog_ms > 0 ? (c2 | sm::kWatchdogTrigger) : (c2 & ~sm::kWatchdogTrigger));
  uint8_t sms[16] = {};
  SmEntry{s.sm2_start, out_bytes, c2, 0, static_cast<uint8_t>(out_bytes ? 1 : 0), 0}.encode(sms);
  SmEntry{s.sm3_start, in_bytes, c3, 0, static_cast<uint8_t>(in_bytes ? 1 : 0), 0}.encode(sms + 8);
  must_write(s, reg::kSm0 + 16, sms, 16, "SM2/SM3 (process data)");
  uint8_t f[32] = {};
  if (out_bytes) {
    FmmuEntry e;
    e.logical_start = s.out_bit / 8;
    e.length = out_bytes;
    e.physical_start = s.sm2_start;
    e.type = 2;
    e.activate = 1;
    e.encode(f);
  }
  if (in_bytes) {
    FmmuEntry e;
    e.logical_start = static_cast<uint32_t>(outputs_.size()) + s.in_bit / 8;
    e.length = in_bytes;
    e.physical_start = s.sm3_start;
    e.type = 1;
    e.activate = 1;
    e.encode(f + 16);
  }
  must_write(s, reg::kFmmu0, f, 32, "FMMU0/FMMU1");
  // Divider for 100 us units, then the time (0 switches it off), each read
  // back: a slave that kept other values would be watched differently
  // from what the INI says.
  const auto time = static_cast<uint16_t>(std::min<uint32_t>(watchdog_ms * 10, 0xFFFF));
  const struct {
    uint16_t reg, value;
    const char* what;
  } writes[] = {{reg::kWatchdogDivider, kWatchdogDivider100us, "watchdog divider"},
                {reg::kWatchdogPd, time, "process-data watchdog time"}};
  for (const auto& w : writes) {
    uint8_t wd[2];
    put16(wd, w.value);
    must_write(s, w.reg, wd, 2, w.what);
    uint8_t back[2] = {};
    if (fprd(s, w.reg, back, 2) != 1) fail_slave(s, fmt("reading back %s (register 0x%04X) got no answer", w.what, w.reg));
    if (get16(back) != w.value) {
      fail_slave(s, fmt("%s (register 0x%04X) reads %u after %u was written (WATCHDOG_MS = %u)", w.what, w.reg,
                        get16(back), w.value, watchdog_ms));
    }
  }
}

ProcessSlot Master::output(unsigned position, uint16_t index, uint8_t sub) const noexcept {
  if (position < 1 || position > slaves_.size()) return {};
  const SlaveInfo& s = slaves_[position - 1];
  uint32_t bit = s.out_bit;
  for (const auto& e : s.rx) {
    if (e.index == index && e.sub == sub) {
      return ProcessSlot{const_cast<uint8_t*>(outputs_.data()), static_cast<uint16_t>(bit), e.bits};
    }
    bit += e.bits;
  }
  return {};
}

ProcessSlot Master::input(unsigned position, uint16_t index, uint8_t sub) const noexcept {
  if (position < 1 || position > slaves_.size()) return {};
  const SlaveInfo& s = slaves_[position - 1];
  uint32_t bit = s.in_bit;
  for (const auto& e : s.tx) {
    if (e.index == index && e.sub == sub) {
      return ProcessSlot{const_cast<uint8_t*>(inputs_.data()), static_cast<uint16_t>(bit), e.bits};
    }
    bit += e.bits;
  }
  return {};
}

// ---------------------------------------------------------------- DC

void Master::configure_dc() {
  dc_ref_ = -1;
  if (!cfg_.dc) return;
  std::vector<std::size_t> dc;
  for (std::size_t i = 0; i < slaves_.size(); ++i) {
    if (slaves_[i].has_dc) dc.push_back(i);
  }
  if (dc.empty()) return;
  dc_ref_ = static_cast<int>(dc.front());
  uint8_t latch[4] = {};
  if (!transact(Command::BWR, physical_address(0, reg::kDcPortTime0), latch, 4)) fail("DC: the receive-time latch got no reply");
  const int64_t master_time = monotonic_ns();
  std::vector<PortTimes> t(dc.size());
  for (std::size_t k = 0; k < dc.size(); ++k) {
    SlaveInfo& s = slaves_[dc[k]];
    uint8_t p[8] = {}, l[8] = {};
    if (fprd(s, reg::kDcPortTime0, p, 8) != 1 || fprd(s, reg::kDcReceiveTimePu, l, 8) != 1) {
      fail_slave(s, "DC: reading the receive times got no answer");
    }
    t[k].port0 = get32(p);
    t[k].port1 = get32(p + 4);
    t[k].port1_open = s.port1_open && k + 1 < dc.size();
    t[k].local_at_latch = static_cast<int64_t>(get64(l));
  }
  const std::vector<int64_t> delays = line_delays(t);
  const std::vector<int64_t> offsets = system_offsets(t, delays, master_time - t[0].local_at_latch);
  for (std::size_t k = 0; k < dc.size(); ++k) {
    SlaveInfo& s = slaves_[dc[k]];
    s.dc_delay_ns = delays[k];
    s.dc_offset_ns = offsets[k];
    uint8_t o[8], d[4];
    put64(o, static_cast<uint64_t>(offsets[k]));
    put32(d, static_cast<uint32_t>(delays[k]));
    must_write(s, reg::kDcSystemOffset, o, 8, "DC system time offset");
    must_write(s, reg::kDcSystemDelay, d, 4, "DC system time delay");
  }
  const SlaveInfo& ref = slaves_[dc.front()];
  for (unsigned k = 0; k < cfg_.dc_static_drift_frames; ++k) {
    uint8_t st[8] = {};
    (void)transact(Command::FRMW, physical_address(ref.station, reg::kDcSystemTime), st, 8);
  }
  uint8_t st[8] = {};
  if (fprd(ref, reg::kDcSystemTime, st, 8) != 1) fail_slave(ref, "DC: reading the system time got no answer");
  const int64_t c = cfg_.cycle_ns;
  const int64_t shift = cfg_.sync0_shift_ns >= 0 ? cfg_.sync0_shift_ns : c / 2;
  const int64_t start = ((static_cast<int64_t>(get64(st)) + 100'000'000) / c + 1) * c + shift;
  for (std::size_t i : dc) {
    SlaveInfo& s = slaves_[i];
    const SlaveConfig* sc = cfg_.slave(s.position);
    if ((sc && !sc->sync0) || (s.assign_activate & 0x0200) == 0) continue;
    uint8_t off[1] = {0}, cyc[8] = {}, t0[8], act[2];
    put16(act, s.assign_activate);  // ESI AssignActivate: 0x0300 SYNC0, 0x0700 SYNC0 + SYNC1
    put32(cyc, static_cast<uint32_t>(c));
    put64(t0, static_cast<uint64_t>(start));
    must_write(s, reg::kDcActivation, off, 1, "DC activation (off)");
    must_write(s, reg::kDcSync0Cycle, cyc, 8, "SYNC0/SYNC1 cycle time");
    must_write(s, reg::kDcStartTime, t0, 8, "DC start time");
    must_write(s, reg::kDcCyclicControl, act, 2, "DC activation (SYNC0)");
  }
  PhaseLock::Options o;
  o.cycle_ns = c;
  o.target_ns = 0;  // frames pass the reference half a cycle before SYNC0
  lock_ = PhaseLock(o);
}

// ---------------------------------------------------------------- start-up

void Master::plan() {
  if (!scanned_) scan();
  for (SlaveInfo& s : slaves_) {
    const SlaveConfig* c = cfg_.slave(s.position);
    auto from_sii = [](const std::vector<SiiPdo>& pdos) {
      std::vector<PdoEntryConfig> v;
      for (const SiiPdo& p : pdos) {
        for (const SiiPdoEntry& e : p.entries) v.push_back({e.index, e.sub, e.bits});
      }
      return v;
    };
    const std::vector<SiiPdo>* rx_defaults = &s.sii.rx_pdos;
    const std::vector<SiiPdo>* tx_defaults = &s.sii.tx_pdos;
    EsiFile esi;
    if (c && !c->esi.empty()) {
#ifdef CNC_ETHERCAT_ESI
      try {
        esi = load_esi(c->esi);
      } catch (const std::exception& e) {
        fail_slave(s, std::string("ESI: ") + e.what());
      }
      if (esi.vendor_id != s.sii.vendor_id) {
        fail_slave(s, fmt("ESI %s is for vendor 0x%08X, the slave's SII says 0x%08X", c->esi.c_str(), esi.vendor_id,
                          s.sii.vendor_id));
      }
      const EsiDevice* d = esi.find(s.sii.product_code, s.sii.revision);
      if (!d) {
        fail_slave(s, fmt("ESI %s describes no device with product code 0x%08X (the slave's SII)", c->esi.c_str(),
                          s.sii.product_code));
      }
      rx_defaults = &d->rx_pdos;
      tx_defaults = &d->tx_pdos;
      s.assign_activate = d->has_dc ? d->assign_activate : 0;
      s.esi_device = fmt("%s (%s:%d)", d->type.c_str(), c->esi.c_str(), d->line);
#else
      fail_slave(s, "ESI = " + c->esi + ": this build has no ESI support (libexpat1-dev was missing)");
#endif
    }
    s.rx = c && c->rx_pdo ? *c->rx_pdo : from_sii(*rx_defaults);
    s.tx = c && c->tx_pdo ? *c->tx_pdo : from_sii(*tx_defaults);
  }
  layout_process_data();
  planned_ = true;
}

void Master::to_preop() {
  if (!scanned_) scan();
  for (SlaveInfo& s : slaves_) configure_mailbox(s);
  for (SlaveInfo& s : slaves_) request_state(s, AlState::PreOp);
}

void Master::start_up() {
  if (!planned_) plan();
  for (SlaveInfo& s : slaves_) configure_mailbox(s);
  for (SlaveInfo& s : slaves_) request_state(s, AlState::PreOp);
  for (SlaveInfo& s : slaves_) configure_coe(s);
  for (SlaveInfo& s : slaves_) configure_process_data(s);
  configure_dc();
  prepare_cyclic();
  for (SlaveInfo& s : slaves_) request_state(s, AlState::SafeOp);
  drain(*cyclic_link_);  // start-up replies the cyclic socket saw too
  good_cycles_.store(0);
  phase_.store(BusPhase::SafeOp, std::memory_order_release);
  post(false, fmt("%zu slave%s in SAFEOP on %s: outputs %zu B, inputs %zu B, expected working counter %u%s",
                  slaves_.size(), slaves_.size() == 1 ? "" : "s", acyclic_link_->name().c_str(), outputs_.size(),
                  inputs_.size(), expected_wkc_,
                  dc_ref_ >= 0 ? fmt(", DC reference %s", slave_label(slaves_[dc_ref_].position).c_str()).c_str() : ""));
}

void Master::prepare_cyclic() {
  FrameBuilder fb;
  fb.begin(tx_.data(), cyclic_link_->mac());
  const auto total = static_cast<uint16_t>(outputs_.size() + inputs_.size());
  DatagramRef d = fb.add(Command::LRW, 0, 0, total);
  lrw_offset_ = static_cast<std::size_t>(d.data() - tx_.data());
  frmw_offset_ = diff_offset_ = 0;
  if (dc_ref_ >= 0) {
    d = fb.add(Command::FRMW, 0, physical_address(slaves_[dc_ref_].station, reg::kDcSystemTime), 8);
    frmw_offset_ = static_cast<std::size_t>(d.data() - tx_.data());
  }
  d = fb.add(Command::BRD, 0, physical_address(0, reg::kAlStatus), 2);
  al_offset_ = static_cast<std::size_t>(d.data() - tx_.data());
  if (dc_ref_ >= 0) {
    d = fb.add(Command::BRD, 0, physical_address(0, reg::kDcSystemDiff), 4);
    diff_offset_ = static_cast<std::size_t>(d.data() - tx_.data());
  }
  tx_size_ = fb.finish();
}

// ---------------------------------------------------------------- cycle

void Master::cyclic_write(int64_t) noexcept {
  const BusPhase ph = phase_.load(std::memory_order_acquire);
  if (ph == BusPhase::Down) return;
  cyclic_index_ = static_cast<uint8_t>((cyclic_index_ + 1) & 0x7F);
  for (std::size_t off : {lrw_offset_, frmw_offset_, al_offset_, diff_offset_}) {
    if (off == 0) continue;
    DatagramRef d(tx_.data() + off - kDatagramHeader);
    tx_[off - kDatagramHeader + 1] = cyclic_index_;
    std::memset(d.data(), 0, d.length());
    d.set_wkc(0);
  }
  if (!outputs_.empty()) std::memcpy(tx_.data() + lrw_offset_, outputs_.data(), outputs_.size());
  if (cyclic_link_->send(tx_.data(), tx_size_)) {
    counters_.frames_sent.fetch_add(1, std::memory_order_relaxed);
    outstanding_ = true;
    sent_in_op_ = ph == BusPhase::Op;
    if (cfg_.spin_for_reply_ns > 0) spin_for_reply();
  } else {
    counters_.send_errors.fetch_add(1, std::memory_order_relaxed);
    outstanding_ = false;
  }
}

void Master::spin_for_reply() noexcept {
  const int64_t t0 = monotonic_ns();
  while (monotonic_ns() - t0 < cfg_.spin_for_reply_ns) {
    const std::size_t n = cyclic_link_->receive(held_.data(), 0);
    if (n == 0) continue;
    FrameView v;
    if (parse_frame(held_.data(), n, v) != ParseResult::Ok || v.datagrams[0].index() != cyclic_index_) continue;
    rtt_.add(monotonic_ns() - t0);
    held_size_ = n;
    return;
  }
}

void Master::cyclic_read(int64_t) noexcept {
  const BusPhase ph = phase_.load(std::memory_order_acquire);
  if (ph == BusPhase::Down) return;
  bool got = false, good = false;
  for (;;) {
    std::size_t n = 0;
    if (held_size_ > 0) {
      std::memcpy(rx_.data(), held_.data(), held_size_);
      n = held_size_;
      held_size_ = 0;
    } else {
      n = cyclic_link_->receive(rx_.data(), 0);
    }
    if (n == 0) break;
    FrameView v;
    if (parse_frame(rx_.data(), n, v) != ParseResult::Ok) continue;
    const uint8_t idx = v.datagrams[0].index();
    if (idx & 0x80) continue;  // the worker's
    if (!outstanding_ || idx != cyclic_index_ || got) {
      counters_.frames_late.fetch_add(1, std::memory_order_relaxed);
      continue;
    }
    got = true;
    const DatagramRef lrw(rx_.data() + lrw_offset_ - kDatagramHeader);
    const uint16_t wkc = lrw.wkc();
    counters_.last_wkc.store(wkc, std::memory_order_relaxed);
    good = wkc == expected_wkc_;
    if (good) {
      if (!inputs_.empty()) std::memcpy(inputs_.data(), lrw.data() + outputs_.size(), inputs_.size());
    } else {
      counters_.wkc_errors.fetch_add(1, std::memory_order_relaxed);
      bad_wkc_.store(static_cast<int32_t>(wkc), std::memory_order_relaxed);
    }
    if (frmw_offset_ && cfg_.dc_lock) {
      const DatagramRef f(rx_.data() + frmw_offset_ - kDatagramHeader);
      if (f.wkc() > 0) phase_adjust_.fetch_add(lock_.update(static_cast<int64_t>(get64(f.data()))), std::memory_order_relaxed);
    }
    if (diff_offset_) {
      const DatagramRef f(rx_.data() + diff_offset_ - kDatagramHeader);
      counters_.dc_sync_diff_ns.store(get32(f.data()) & 0x7FFFFFFF, std::memory_order_relaxed);
    }
    const DatagramRef al(rx_.data() + al_offset_ - kDatagramHeader);
    const uint16_t al_or = get16(al.data());
    counters_.al_status_or.store(al_or, std::memory_order_relaxed);
    if (ph == BusPhase::Op && sent_in_op_ && (al_or & 0x1F) != static_cast<uint8_t>(AlState::Op) && al.wkc() > 0) {
      al_changed_.store(true, std::memory_order_relaxed);
      good = false;
    }
  }
  if (!outstanding_ && !got) return;  // nothing was sent last cycle (first cycle, send error counted there)
  if (outstanding_ && !got) counters_.frames_lost.fetch_add(1, std::memory_order_relaxed);
  outstanding_ = false;
  counters_.inputs_fresh.store(good, std::memory_order_relaxed);
  counters_.cycles.fetch_add(1, std::memory_order_relaxed);
  if (good) {
    counters_.consecutive_bad.store(0, std::memory_order_relaxed);
    bad_wkc_.store(-1, std::memory_order_relaxed);
    good_cycles_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  const uint32_t bad = counters_.consecutive_bad.fetch_add(1, std::memory_order_relaxed) + 1;
  const bool al_dropped = al_changed_.load(std::memory_order_relaxed);
  if ((ph == BusPhase::SafeOp || ph == BusPhase::Op) &&
      (al_dropped || (cfg_.miss_limit > 0 && bad >= cfg_.miss_limit))) {
    fault_wkc_.store(counters_.last_wkc.load(std::memory_order_relaxed), std::memory_order_relaxed);
    fault_bad_.store(bad, std::memory_order_relaxed);
    fault_lost_.store(!got, std::memory_order_relaxed);
    phase_.store(BusPhase::Fault, std::memory_order_release);  // the worker sees it within a millisecond
  }
}

// ---------------------------------------------------------------- mailbox

bool Master::mailbox_write(SlaveInfo& s, const uint8_t* data, std::size_t size, std::string& error) {
  const uint16_t n = s.sii.mailbox_rx_size;
  if (n == 0 || size > n) {
    error = "no mailbox";
    return false;
  }
  std::vector<uint8_t> buf(n, 0);
  std::memcpy(buf.data(), data, size);
  const int64_t deadline = monotonic_ns() + cfg_.mailbox_timeout_ms * 1'000'000;
  for (;;) {
    if (fpwr(s, s.sii.mailbox_rx_offset, buf.data(), n) == 1) return true;
    if (monotonic_ns() > deadline) {
      error = fmt("mailbox not accepted within %lld ms (SM0 full or no answer)", static_cast<long long>(cfg_.mailbox_timeout_ms));
      return false;
    }
    sleep_ns(200'000);
  }
}

bool Master::mailbox_read(SlaveInfo& s, std::vector<uint8_t>& out, int64_t timeout_ns, std::string& error) {
  const int64_t deadline = monotonic_ns() + timeout_ns;
  const uint16_t n = s.sii.mailbox_tx_size;
  for (;;) {
    uint8_t st[1] = {};
    if (fprd(s, reg::kSm0 + 8 + 5, st, 1) == 1 && (st[0] & sm::kStatusFull)) {
      out.assign(n, 0);
      if (fprd(s, s.sii.mailbox_tx_offset, out.data(), n) == 1) return true;
    }
    if (monotonic_ns() > deadline) {
      error = fmt("no answer within %lld ms", static_cast<long long>(timeout_ns / 1'000'000));
      return false;
    }
    sleep_ns(50'000);
  }
}

void Master::handle_emergency(SlaveInfo& s, const uint8_t* d) {
  const uint16_t code = get16(d);
  const uint8_t reg = d[2];
  SlaveState& st = state_[s.position - 1];
  st.emcy_code.store(code);
  st.emcy_count.fetch_add(1);
  if (code == 0) {
    post(false, slave_label(s.position) + ": EMCY 0x0000 error reset");
  } else {
    post(true, fmt("%s: EMCY 0x%04X %s (error register 0x%02X)", slave_label(s.position).c_str(), code,
                   cia402::error_code_text(code), reg));
  }
}

bool Master::coe_exchange(SlaveInfo& s, const uint8_t* sdo, std::size_t n, std::vector<uint8_t>& reply,
                          std::string& error) {
  std::vector<uint8_t> m(kMailboxHeader + 2 + std::max<std::size_t>(n, 8), 0);
  MailboxHeader h;
  h.length = static_cast<uint16_t>(2 + std::max<std::size_t>(n, 8));
  h.type = MailboxType::CoE;
  SlaveState& st = state_[s.position - 1];
  st.mailbox_counter = static_cast<uint8_t>(st.mailbox_counter % 7 + 1);
  h.counter = st.mailbox_counter;
  h.encode(m.data());
  put16(m.data() + kMailboxHeader, coe_header(CoeService::SdoRequest));
  std::memcpy(m.data() + kMailboxHeader + 2, sdo, n);
  if (!mailbox_write(s, m.data(), m.size(), error)) return false;
  std::vector<uint8_t> in;
  for (;;) {
    if (!mailbox_read(s, in, cfg_.mailbox_timeout_ms * 1'000'000, error)) return false;
    const MailboxHeader r = MailboxHeader::decode(in.data());
    if (r.length + kMailboxHeader > in.size() || r.length < 2) {
      error = "malformed mailbox reply (length " + std::to_string(r.length) + ")";
      return false;
    }
    const uint8_t* body = in.data() + kMailboxHeader;
    if (r.type == MailboxType::Error) {
      const uint16_t detail = r.length >= 4 ? get16(body + 2) : 0;
      error = fmt("mailbox error %u: %s", detail, mailbox_error_text(detail));
      return false;
    }
    if (r.type != MailboxType::CoE) continue;
    const CoeService svc = coe_service(get16(body));
    if (svc == CoeService::Emergency && r.length >= 10) {
      handle_emergency(s, body + 2);
      continue;
    }
    if (svc != CoeService::SdoResponse && svc != CoeService::SdoRequest) continue;
    reply.assign(body + 2, body + r.length);
    return true;
  }
}

SdoResult Master::do_download(SlaveInfo& s, uint16_t index, uint8_t sub, const std::vector<uint8_t>& data, bool ca) {
  const uint8_t ca_bit = ca ? 0x10 : 0x00;
  SdoResult res;
  std::vector<uint8_t> r;
  auto check = [&](uint8_t expect) {
    if (r.size() >= 8 && r[0] == 0x80) {
      res.abort_code = get32(r.data() + 4);
      res.error = abort_text(res.abort_code);
      return false;
    }
    if (r.size() < 1 || (r[0] & 0xF0) != (expect & 0xF0) || (expect == 0x60 && r.size() >= 4 && (get16(r.data() + 1) != index || r[3] != sub))) {
      res.error = fmt("unexpected SDO reply 0x%02X", r.empty() ? 0 : r[0]);
      return false;
    }
    return true;
  };
  const std::size_t n = data.size();
  if (n >= 1 && n <= 4) {
    uint8_t q[8] = {static_cast<uint8_t>(0x23 | ca_bit | ((4 - n) << 2))};
    put16(q + 1, index);
    q[3] = sub;
    std::memcpy(q + 4, data.data(), n);
    if (!coe_exchange(s, q, 8, r, res.error) || !check(0x60)) return res;
    res.ok = true;
    return res;
  }
  const std::size_t first_room = s.sii.mailbox_rx_size - kMailboxHeader - 2 - 8;
  const std::size_t here = std::min(n, first_room);
  std::vector<uint8_t> q(8 + here, 0);
  q[0] = static_cast<uint8_t>(0x21 | ca_bit);
  put16(q.data() + 1, index);
  q[3] = sub;
  put32(q.data() + 4, static_cast<uint32_t>(n));
  std::memcpy(q.data() + 8, data.data(), here);
  if (!coe_exchange(s, q.data(), q.size(), r, res.error) || !check(0x60)) return res;
  std::size_t pos = here;
  uint8_t toggle = 0;
  const std::size_t seg_room = s.sii.mailbox_rx_size - kMailboxHeader - 2 - 1;
  while (pos < n) {
    const std::size_t k = std::min(n - pos, seg_room);
    const bool last = pos + k == n;
    std::vector<uint8_t> seg(std::max<std::size_t>(1 + k, 8), 0);
    seg[0] = static_cast<uint8_t>((toggle << 4) | (last ? 1 : 0) | (k < 7 ? (7 - k) << 1 : 0));
    std::memcpy(seg.data() + 1, data.data() + pos, k);
    if (!coe_exchange(s, seg.data(), seg.size(), r, res.error)) return res;
    if (!check(static_cast<uint8_t>(0x20 | (toggle << 4)))) return res;
    if (((r[0] >> 4) & 1) != toggle) {
      res.error = "segment toggle bit not alternated by the slave";
      return res;
    }
    toggle ^= 1;
    pos += k;
  }
  res.ok = true;
  return res;
}

SdoResult Master::do_upload(SlaveInfo& s, uint16_t index, uint8_t sub, bool ca) {
  SdoResult res;
  std::vector<uint8_t> r;
  uint8_t q[8] = {static_cast<uint8_t>(ca ? 0x50 : 0x40)};
  put16(q + 1, index);
  q[3] = sub;
  if (!coe_exchange(s, q, 8, r, res.error)) return res;
  if (r.size() >= 8 && r[0] == 0x80) {
    res.abort_code = get32(r.data() + 4);
    res.error = abort_text(res.abort_code);
    return res;
  }
  if (r.size() < 8 || (r[0] >> 5) != 2 || get16(r.data() + 1) != index || r[3] != sub) {
    res.error = fmt("unexpected SDO reply 0x%02X", r.empty() ? 0 : r[0]);
    return res;
  }
  if (r[0] & 0x02) {  // expedited
    const std::size_t size = (r[0] & 0x01) ? 4u - ((r[0] >> 2) & 3u) : 4u;
    res.data.assign(r.begin() + 4, r.begin() + 4 + static_cast<long>(size));
    res.ok = true;
    return res;
  }
  const std::size_t size = get32(r.data() + 4);
  res.data.assign(r.begin() + 8, r.begin() + 8 + static_cast<long>(std::min(size, r.size() - 8)));
  uint8_t toggle = 0;
  while (res.data.size() < size) {
    uint8_t sq[8] = {static_cast<uint8_t>(0x60 | (toggle << 4))};
    if (!coe_exchange(s, sq, 8, r, res.error)) return res;
    if (r.size() >= 8 && r[0] == 0x80) {
      res.abort_code = get32(r.data() + 4);
      res.error = abort_text(res.abort_code);
      return res;
    }
    if (r.empty() || (r[0] >> 5) != 0 || ((r[0] >> 4) & 1) != toggle) {
      res.error = fmt("unexpected upload segment 0x%02X", r.empty() ? 0 : r[0]);
      return res;
    }
    const std::size_t avail = r.size() - 1;
    const std::size_t bytes = avail == 7 ? 7 - ((r[0] >> 1) & 7) : avail;
    res.data.insert(res.data.end(), r.begin() + 1, r.begin() + 1 + static_cast<long>(std::min(bytes, size - res.data.size())));
    toggle ^= 1;
    if (r[0] & 1) break;
  }
  if (res.data.size() != size) {
    res.error = fmt("upload ended after %zu of %zu bytes", res.data.size(), size);
    return res;
  }
  res.ok = true;
  return res;
}

SdoResult Master::do_info(SlaveInfo& s, uint8_t opcode, const std::vector<uint8_t>& request) {
  SdoResult res;
  std::vector<uint8_t> m(kMailboxHeader + 2 + 4 + request.size(), 0);
  MailboxHeader h;
  h.length = static_cast<uint16_t>(2 + 4 + request.size());
  h.type = MailboxType::CoE;
  SlaveState& st = state_[s.position - 1];
  st.mailbox_counter = static_cast<uint8_t>(st.mailbox_counter % 7 + 1);
  h.counter = st.mailbox_counter;
  h.encode(m.data());
  put16(m.data() + kMailboxHeader, coe_header(CoeService::SdoInfo));
  m[kMailboxHeader + 2] = opcode;
  std::copy(request.begin(), request.end(), m.begin() + kMailboxHeader + 6);
  if (!mailbox_write(s, m.data(), m.size(), res.error)) return res;
  std::vector<uint8_t> in;
  for (;;) {
    if (!mailbox_read(s, in, cfg_.mailbox_timeout_ms * 1'000'000, res.error)) return res;
    const MailboxHeader r = MailboxHeader::decode(in.data());
    if (r.length + kMailboxHeader > in.size() || r.length < 2) {
      res.error = "malformed mailbox reply";
      return res;
    }
    const uint8_t* body = in.data() + kMailboxHeader;
    if (r.type == MailboxType::Error) {
      const uint16_t detail = r.length >= 4 ? get16(body + 2) : 0;
      res.error = fmt("mailbox error %u: %s", detail, mailbox_error_text(detail));
      return res;
    }
    if (r.type != MailboxType::CoE) continue;
    const CoeService svc = coe_service(get16(body));
    if (svc == CoeService::Emergency && r.length >= 10) {
      handle_emergency(s, body + 2);
      continue;
    }
    if (svc != CoeService::SdoInfo || r.length < 6) continue;
    const uint8_t op = body[2] & 0x7F;
    if (op == 7) {
      res.abort_code = r.length >= 10 ? get32(body + 6) : 0;
      res.error = abort_text(res.abort_code);
      return res;
    }
    res.data.insert(res.data.end(), body + 6, body + r.length);
    if (get16(body + 4) == 0) break;  // no fragments left
  }
  res.ok = true;
  return res;
}

std::vector<uint16_t> Master::sdo_info_list(unsigned position, std::string& error) {
  SlaveInfo* s = find(position);
  if (!s) {
    error = fmt("no slave at position %u", position);
    return {};
  }
  const SdoResult r = run_on_worker([=, this] { return do_info(*s, 1, le(1, 2)); });
  std::vector<uint16_t> out;
  if (!r.ok) {
    error = r.error;
    return out;
  }
  for (std::size_t i = 2; i + 1 < r.data.size(); i += 2) out.push_back(get16(r.data.data() + i));
  return out;
}

std::optional<SdoInfoObject> Master::sdo_info_object(unsigned position, uint16_t index, std::string& error) {
  SlaveInfo* s = find(position);
  if (!s) {
    error = fmt("no slave at position %u", position);
    return std::nullopt;
  }
  const SdoResult r = run_on_worker([=, this] { return do_info(*s, 3, le(index, 2)); });
  if (!r.ok || r.data.size() < 6) {
    error = r.ok ? "object description too short" : r.error;
    return std::nullopt;
  }
  SdoInfoObject o;
  o.index = get16(r.data.data());
  o.data_type = get16(r.data.data() + 2);
  o.max_sub = r.data[4];
  o.object_code = r.data[5];
  o.name.assign(r.data.begin() + 6, r.data.end());
  return o;
}

std::optional<SdoInfoEntry> Master::sdo_info_entry(unsigned position, uint16_t index, uint8_t sub, std::string& error) {
  SlaveInfo* s = find(position);
  if (!s) {
    error = fmt("no slave at position %u", position);
    return std::nullopt;
  }
  std::vector<uint8_t> q = le(index, 2);
  q.push_back(sub);
  q.push_back(0x01);  // value info: access rights
  const SdoResult r = run_on_worker([=, this] { return do_info(*s, 5, q); });
  if (!r.ok || r.data.size() < 10) {
    error = r.ok ? "entry description too short" : r.error;
    return std::nullopt;
  }
  SdoInfoEntry e;
  e.index = get16(r.data.data());
  e.sub = r.data[2];
  e.data_type = get16(r.data.data() + 4);
  e.bit_length = get16(r.data.data() + 6);
  e.access = get16(r.data.data() + 8);
  e.name.assign(r.data.begin() + 10, r.data.end());
  return e;
}

SdoResult Master::run_on_worker(std::function<SdoResult()> job) {
  if (!worker_.joinable() || std::this_thread::get_id() == worker_id_) return job();
  std::promise<SdoResult> p;
  auto f = p.get_future();
  {
    std::lock_guard lock(jobs_mutex_);
    jobs_.push_back([&] { p.set_value(job()); });
  }
  jobs_cv_.notify_all();
  return f.get();
}

SdoResult Master::sdo_upload(unsigned position, uint16_t index, uint8_t sub, bool ca) {
  SlaveInfo* s = find(position);
  if (!s) return SdoResult{false, 0, {}, fmt("no slave at position %u", position)};
  return run_on_worker([=, this] { return do_upload(*s, index, sub, ca); });
}

SdoResult Master::sdo_download(unsigned position, uint16_t index, uint8_t sub, const std::vector<uint8_t>& data,
                               bool ca) {
  SlaveInfo* s = find(position);
  if (!s) return SdoResult{false, 0, {}, fmt("no slave at position %u", position)};
  return run_on_worker([=, this] { return do_download(*s, index, sub, data, ca); });
}

int Master::rt_sdo_read(unsigned position, uint16_t index, uint8_t sub) noexcept {
  for (std::size_t i = 0; i < rt_.size(); ++i) {
    RtRequest& r = rt_[i];
    if (r.state.load(std::memory_order_acquire) != 0) continue;
    r.position = position;
    r.index = index;
    r.sub = sub;
    r.write = false;
    r.state.store(1, std::memory_order_release);
    return static_cast<int>(i);
  }
  return -1;
}

int Master::rt_sdo_write(unsigned position, uint16_t index, uint8_t sub, uint32_t value, uint8_t size) noexcept {
  for (std::size_t i = 0; i < rt_.size(); ++i) {
    RtRequest& r = rt_[i];
    if (r.state.load(std::memory_order_acquire) != 0) continue;
    r.position = position;
    r.index = index;
    r.sub = sub;
    r.write = true;
    r.value = value;
    r.size = size;
    r.state.store(1, std::memory_order_release);
    return static_cast<int>(i);
  }
  return -1;
}

bool Master::rt_sdo_poll(int handle, uint32_t& abort_code, uint32_t& value) noexcept {
  if (handle < 0 || static_cast<std::size_t>(handle) >= rt_.size()) return false;
  RtRequest& r = rt_[static_cast<std::size_t>(handle)];
  if (r.state.load(std::memory_order_acquire) != 2) return false;
  abort_code = r.abort_code;
  value = r.result;
  r.state.store(0, std::memory_order_release);
  return true;
}

// ---------------------------------------------------------------- worker

void Master::start_worker() {
  if (worker_.joinable()) return;
  stop_.store(false);
  worker_ = std::thread([this] { worker_loop(); });
}

void Master::worker_rt_requests() {
  for (RtRequest& r : rt_) {
    if (r.state.load(std::memory_order_acquire) != 1) continue;
    SlaveInfo* s = find(r.position);
    SdoResult res;
    if (!s) res.abort_code = canopen::abort_code::kNoObject;
    else if (r.write) res = do_download(*s, r.index, r.sub, le(r.value, r.size ? r.size : 4));
    else res = do_upload(*s, r.index, r.sub);
    r.abort_code = res.ok ? 0 : (res.abort_code ? res.abort_code : canopen::abort_code::kTimeout);
    r.result = 0;
    for (std::size_t i = 0; i < res.data.size() && i < 4; ++i) r.result |= uint32_t{res.data[i]} << (8 * i);
    r.state.store(2, std::memory_order_release);
  }
}

void Master::worker_go_op() {
  try {
    for (SlaveInfo& s : slaves_) request_state(s, AlState::Op);
  } catch (const StartupError& e) {
    {
      std::lock_guard lock(fault_mutex_);
      fault_text_ = e.what();
    }
    phase_.store(BusPhase::Fault, std::memory_order_release);
    fault_reported_ = true;
    post(true, e.what());
    return;
  }
  counters_.consecutive_bad.store(0);
  BusPhase expected = BusPhase::SafeOp;
  if (phase_.compare_exchange_strong(expected, BusPhase::Op)) {
    post(false, fmt("%zu slave%s in OP, cycle %lld us", slaves_.size(), slaves_.size() == 1 ? "" : "s",
                    static_cast<long long>(cfg_.cycle_ns / 1000)));
  }
}

void Master::worker_report_fault() {
  fault_reported_ = true;
  const bool al = al_changed_.load();
  std::string text = "safe stop: ";
  if (al) {
    text += "a slave left OP";
  } else {
    std::string last = fault_lost_.load() ? std::string("last frame lost")
                                          : fmt("last working counter %u, expected %u", fault_wkc_.load(), expected_wkc_);
    if (fault_lost_.load() && bad_wkc_.load() >= 0) {
      last += fmt(", last wrong working counter %d, expected %u", bad_wkc_.load(), expected_wkc_);
    }
    text += fmt("%u consecutive cycles without valid process data (%s; frames lost %llu, "
                "late %llu, working-counter errors %llu)",
                fault_bad_.load(), last.c_str(),
                static_cast<unsigned long long>(counters_.frames_lost.load()),
                static_cast<unsigned long long>(counters_.frames_late.load()),
                static_cast<unsigned long long>(counters_.wkc_errors.load()));
  }
  uint8_t b[2] = {};
  const auto count = transact(Command::BRD, 0, b, 2);
  if (!count) {
    text += "; no frame comes back at all (cable to the first slave, interface down?)";
  } else if (*count < slaves_.size()) {
    text += fmt("; only %u of %zu slaves answer: link lost after %s (cable break or power?)", *count, slaves_.size(),
                *count == 0 ? "the master" : slave_label(*count).c_str());
  }
  for (SlaveInfo& s : slaves_) {
    if (!count || s.position > *count) break;  // unreachable: do not wait for each of them
    uint8_t st[6] = {};
    if (fprd(s, reg::kAlStatus, st, 6) != 1) continue;
    state_[s.position - 1].al_state.store(st[0] & 0x0F);
    state_[s.position - 1].al_code.store(get16(st + 4));
    if ((st[0] & 0x0F) != static_cast<uint8_t>(AlState::Op) || (st[0] & kAlErrorFlag)) {
      text += fmt("; %s is in %s%s", slave_label(s.position).c_str(), al_state_name(st[0]),
                  (st[0] & kAlErrorFlag) ? "" : "");
      if (st[0] & kAlErrorFlag) {
        text += fmt(" with AL status code 0x%04X %s", get16(st + 4), al_status_text(get16(st + 4)));
      }
    }
  }
  {
    std::lock_guard lock(fault_mutex_);
    fault_text_ = cfg_.name + ": " + text;
  }
  post(true, text);
}

void Master::worker_poll_emergencies() {
  for (SlaveInfo& s : slaves_) {
    if (!s.sii.has_coe()) continue;
    uint8_t st[1] = {};
    if (fprd(s, reg::kSm0 + 8 + 5, st, 1) != 1 || !(st[0] & sm::kStatusFull)) continue;
    std::vector<uint8_t> in;
    std::string error;
    if (!mailbox_read(s, in, 0, error)) continue;
    const MailboxHeader h = MailboxHeader::decode(in.data());
    if (h.type == MailboxType::CoE && h.length >= 10 &&
        coe_service(get16(in.data() + kMailboxHeader)) == CoeService::Emergency) {
      handle_emergency(s, in.data() + kMailboxHeader + 2);
    }
  }
}

void Master::worker_restart() {
  // The servo thread stops touching the frame and the image first.
  phase_.store(BusPhase::Down, std::memory_order_release);
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
  const std::vector<SlaveInfo> before = slaves_;
  const std::size_t out = outputs_.size(), in = inputs_.size();
  try {
    scanned_ = planned_ = false;
    scan();  // refuses another slave count
    // The drives hold slots into the image: the bus must come back as it was.
    for (std::size_t i = 0; i < slaves_.size(); ++i) {
      if (slaves_[i].sii.vendor_id != before[i].sii.vendor_id || slaves_[i].sii.product_code != before[i].sii.product_code ||
          slaves_[i].sii.serial != before[i].sii.serial) {
        fail_slave(slaves_[i], "restart: another device than before at this position");
      }
    }
    plan();
    if (outputs_.size() != out || inputs_.size() != in) fail("restart: the process image changed");
    outstanding_ = false;
    held_size_ = 0;
    lock_.reset();
    al_changed_.store(false);
    counters_.consecutive_bad.store(0);
    start_up();  // ends in SAFEOP; OP follows once the cycle is good
    fault_reported_ = false;
    {
      std::lock_guard lock(fault_mutex_);
      fault_text_.clear();
    }
    post(false, "restarted after the fault: every slave found again");
  } catch (const std::exception& e) {
    for (std::size_t i = 0; i < slaves_.size() && i < before.size(); ++i) slaves_[i] = before[i];
    scanned_ = planned_ = true;
    {
      std::lock_guard lock(fault_mutex_);
      fault_text_ = e.what();
    }
    fault_reported_ = true;
    phase_.store(BusPhase::Fault, std::memory_order_release);
    post(true, e.what());
  }
}

void Master::worker_loop() {
  worker_id_ = std::this_thread::get_id();
  int64_t next_emcy = 0;
  bool op_tried = false;
  while (!stop_.load()) {
    for (;;) {
      std::function<void()> job;
      {
        std::lock_guard lock(jobs_mutex_);
        if (jobs_.empty()) break;
        job = std::move(jobs_.front());
        jobs_.pop_front();
      }
      job();
    }
    worker_rt_requests();
    // Every reply reaches both sockets on a raw link: drop the cyclic ones
    // this socket collected, so that its buffer never fills.
    drain(*acyclic_link_);
    const BusPhase ph = phase();
    if (restart_requested_.exchange(false)) {
      worker_restart();
      op_tried = false;
      continue;
    }
    if (ph == BusPhase::SafeOp && !op_tried && good_cycles_.load() >= cfg_.op_after_good_cycles) {
      op_tried = true;
      worker_go_op();
    }
    if (phase() == BusPhase::Fault && !fault_reported_) worker_report_fault();
    const int64_t now = monotonic_ns();
    if (now >= next_emcy && (ph == BusPhase::SafeOp || ph == BusPhase::Op)) {
      next_emcy = now + 20'000'000;
      worker_poll_emergencies();
    }
    std::unique_lock lock(jobs_mutex_);
    jobs_cv_.wait_for(lock, std::chrono::milliseconds(1), [this] { return !jobs_.empty() || stop_.load(); });
  }
}

// ---------------------------------------------------------------- status

std::string Master::fault_text() const {
  std::lock_guard lock(fault_mutex_);
  return fault_text_;
}

uint8_t Master::slave_al_state(unsigned position) const noexcept {
  return position >= 1 && position <= slaves_.size() ? state_[position - 1].al_state.load() : 0;
}
uint16_t Master::slave_al_code(unsigned position) const noexcept {
  return position >= 1 && position <= slaves_.size() ? state_[position - 1].al_code.load() : 0;
}
uint16_t Master::slave_emcy_code(unsigned position) const noexcept {
  return position >= 1 && position <= slaves_.size() ? state_[position - 1].emcy_code.load() : 0;
}
uint32_t Master::slave_emcy_count(unsigned position) const noexcept {
  return position >= 1 && position <= slaves_.size() ? state_[position - 1].emcy_count.load() : 0;
}

}  // namespace cnc::ethercat
