// The EtherCAT master, configuration: scan and SII, AL state changes, CoE
// start-up objects, process-data layout and mapping, distributed clocks,
// the start-up sequence.
#include "fieldbus/ethercat/master_internal.hpp"

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

using namespace master_detail;

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

void Master::set_cycle_ns(int64_t ns) {
  auto fail = [&](const std::string& what) {
    throw std::runtime_error(cfg_.name + ": with a cycle of " + std::to_string(ns / 1000) + " us " + what);
  };
  if (cfg_.sync0_shift_ns >= ns) fail("SYNC0_SHIFT_US must be shorter than the cycle");
  auto watchdog_ok = [&](uint32_t ms) { return ms == 0 || int64_t{ms} * 1'000'000 >= 2 * ns; };
  if (!watchdog_ok(cfg_.watchdog_ms)) fail("WATCHDOG_MS must be at least two cycles (or 0: off)");
  for (const SlaveConfig& s : cfg_.slaves) {
    if (!watchdog_ok(s.watchdog_ms)) fail("slave " + std::to_string(s.position) + "'s WATCHDOG_MS must be at least two cycles");
  }
  cfg_.cycle_ns = ns;
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
  clear_error_counters();  // what start-up and earlier runs left is not this run's
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

}  // namespace cnc::ethercat
