#include "sim/ethercat/coe_drive.hpp"

#include <algorithm>
#include <cstring>

#include "cia402/profile.hpp"
#include "fieldbus/canopen/pdo.hpp"
#include "fieldbus/canopen/sdo_abort.hpp"
#include "fieldbus/ethercat/sii.hpp"

namespace cnc::ethercat::sim {
namespace {

using canopen::Access;
using canopen::DataType;
namespace ab = canopen::abort_code;

constexpr uint16_t kMailboxOut = 0x1000, kMailboxIn = 0x1080, kMailboxSize = 128;
constexpr uint16_t kOutputs = 0x1100, kInputs = 0x1180;

}  // namespace

std::vector<std::pair<uint32_t, const char*>> default_rx_mapping() {
  return {{0x60400010, "Controlword"}, {0x607A0020, "Target position"}, {0x60600008, "Modes of operation"}};
}
std::vector<std::pair<uint32_t, const char*>> default_tx_mapping() {
  return {{0x60410010, "Statusword"},
          {0x60640020, "Position actual value"},
          {0x60610008, "Modes of operation display"},
          {0x603F0010, "Error code"}};
}

CoeDrive::Comm::Comm(canopen::ObjectDictionary& od, const CoeDriveConfig& c) {
  od.add({0x1000, 0}, DataType::Unsigned32, Access::Const, 0x00020192, false, "Device type");
  od.add({0x1001, 0}, DataType::Unsigned8, Access::ReadOnly, 0, false, "Error register");
  od.add({0x1006, 0}, DataType::Unsigned32, Access::ReadWrite, 0, false, "Communication cycle period (us)");
  od.add_string({0x1008, 0}, Access::Const, c.name, 0, "Device name");
  od.add({0x1018, 0}, DataType::Unsigned8, Access::Const, 4, false, "Identity");
  od.add({0x1018, 1}, DataType::Unsigned32, Access::Const, c.vendor_id, false, "Vendor ID");
  od.add({0x1018, 2}, DataType::Unsigned32, Access::Const, c.product_code, false, "Product code");
  od.add({0x1018, 3}, DataType::Unsigned32, Access::Const, c.revision, false, "Revision");
  od.add({0x1018, 4}, DataType::Unsigned32, Access::Const, c.serial, false, "Serial number");
  const auto rx = default_rx_mapping(), tx = default_tx_mapping();
  for (uint16_t p = 0; p < std::min<uint16_t>(c.pdo_mappings, 32); ++p) {
    for (const bool out : {true, false}) {
      const uint16_t index = static_cast<uint16_t>((out ? 0x1600 : 0x1A00) + p);
      const auto& def = out ? rx : tx;
      od.add({index, 0}, DataType::Unsigned8, Access::ReadWrite, p == 0 ? def.size() : 0, false,
             out ? "RxPDO mapping" : "TxPDO mapping");
      for (uint8_t s = 1; s <= 8; ++s) {
        const uint32_t v = p == 0 && s <= def.size() ? def[s - 1].first : 0;
        od.add({index, s}, DataType::Unsigned32, Access::ReadWrite, v, false, "mapping entry");
      }
    }
  }
  od.add({0x1C00, 0}, DataType::Unsigned8, Access::Const, 4, false, "Sync manager types");
  for (uint8_t s = 1; s <= 4; ++s) od.add({0x1C00, s}, DataType::Unsigned8, Access::Const, s, false, "SM type");
  for (const bool out : {true, false}) {
    const uint16_t index = out ? 0x1C12 : 0x1C13;
    od.add({index, 0}, DataType::Unsigned8, Access::ReadWrite, 1, false, out ? "RxPDO assign" : "TxPDO assign");
    od.add({index, 1}, DataType::Unsigned16, Access::ReadWrite, out ? 0x1600 : 0x1A00, false, "assigned PDO");
    od.add({index, 2}, DataType::Unsigned16, Access::ReadWrite, 0, false, "assigned PDO");
  }
  for (const uint16_t index : {0x1C32, 0x1C33}) {
    od.add({index, 0}, DataType::Unsigned8, Access::Const, 0x20, false, "Sync manager parameter");
    od.add({index, 1}, DataType::Unsigned16, Access::ReadWrite, 1, false, "Synchronization type");
    od.add({index, 2}, DataType::Unsigned32, Access::ReadWrite, 1'000'000, false, "Cycle time");
    od.add({index, 3}, DataType::Unsigned32, Access::ReadWrite, 0, false, "Shift time");
    od.add({index, 4}, DataType::Unsigned16, Access::ReadOnly, 0x0007, false, "Synchronization types supported");
    od.add({index, 5}, DataType::Unsigned32, Access::ReadOnly, 125'000, false, "Minimum cycle time");
    od.add({index, 6}, DataType::Unsigned32, Access::ReadOnly, 20'000, false, "Calc and copy time");
    od.add({index, 9}, DataType::Unsigned32, Access::ReadOnly, 0, false, "Delay time");
    od.add({index, 0x0B}, DataType::Unsigned16, Access::ReadOnly, 0, false, "SM event missed counter");
    od.add({index, 0x0C}, DataType::Unsigned16, Access::ReadOnly, 0, false, "Cycle time too small counter");
    od.add({index, 0x20}, DataType::Boolean, Access::ReadOnly, 0, false, "Sync error");
  }
}

CoeDrive::CoeDrive(const CoeDriveConfig& config, int64_t now_ns)
    : cfg_(config), comm_(od_, cfg_), model_([&] {
        cia402::sim::DriveSimConfig d = config.drive;
        d.name = config.name;
        return d;
      }(), od_) {
  buffer_.reserve(std::max<std::size_t>(od_.max_capacity(), 256));
  rx_map_.reserve(64);
  tx_map_.reserve(64);
  auto mapping_check = [this](const canopen::OdEntry& e, const uint8_t* d, std::size_t n) {
    return check_mapping_write(e, d, n);
  };
  for (uint16_t p = 0; p < std::min<uint16_t>(cfg_.pdo_mappings, 32); ++p) {
    od_.set_write_check(static_cast<uint16_t>(0x1600 + p), mapping_check);
    od_.set_write_check(static_cast<uint16_t>(0x1A00 + p), mapping_check);
  }
  od_.set_write_check(uint16_t{0x1C12}, mapping_check);
  od_.set_write_check(uint16_t{0x1C13}, mapping_check);
  auto sync_check = [](const canopen::OdEntry& e, const uint8_t* d, std::size_t) -> uint32_t {
    if (e.addr.sub == 1 && get16(d) > 2) return ab::kValueRange;
    if (e.addr.sub == 2 && get32(d) != 0 && get32(d) < 125'000) return ab::kValueTooLow;
    return 0;
  };
  od_.set_write_check(uint16_t{0x1C32}, sync_check);
  od_.set_write_check(uint16_t{0x1C33}, sync_check);
  od_.set_after_write({0x1C32, 2}, [this](const canopen::OdEntry&) {
    od_.set<uint32_t>({0x1006, 0}, od_.get<uint32_t>({0x1C32, 2}) / 1000);
  });
  model_.on_emcy = [this](uint16_t code, uint8_t reg) { emergency(code, reg); };
  model_.power_on(now_ns);
  now_ns_ = now_ns;
}

EscConfig CoeDrive::esc_config() const {
  SiiInfo s;
  s.vendor_id = cfg_.vendor_id;
  s.product_code = cfg_.product_code;
  s.revision = cfg_.revision;
  s.serial = cfg_.serial;
  s.mailbox_rx_offset = kMailboxOut;
  s.mailbox_rx_size = kMailboxSize;
  s.mailbox_tx_offset = kMailboxIn;
  s.mailbox_tx_size = kMailboxSize;
  s.mailbox_protocols = 0x0004;
  s.name = cfg_.name;  // one name per simulated drive, so messages tell them apart
  s.order = "CNC-SIM-402";
  s.group = "Drives";
  s.coe_details = 0x2F;  // SDO, SDO info, PDO assign, PDO config, complete access
  s.fmmus = {1, 2, 3};
  s.sms = {{kMailboxOut, kMailboxSize, 0x26, 1, 1}, {kMailboxIn, kMailboxSize, 0x22, 1, 2},
           {kOutputs, 0, cfg_.sm2_control, 1, 3}, {kInputs, 0, 0x20, 1, 4}};
  for (const bool out : {true, false}) {
    SiiPdo p;
    p.index = out ? 0x1600 : 0x1A00;
    p.sm = out ? 2 : 3;
    p.name = out ? "Outputs" : "Inputs";
    for (const auto& [v, name] : out ? default_rx_mapping() : default_tx_mapping()) {
      const auto e = canopen::PdoMapEntry::decode(v);
      const canopen::OdEntry* o = od_.find({e.index, e.sub});
      p.entries.push_back(SiiPdoEntry{e.index, e.sub, e.bits, static_cast<uint8_t>(o ? static_cast<uint16_t>(o->type) : 0), name});
    }
    (out ? s.rx_pdos : s.tx_pdos).push_back(p);
  }
  s.has_dc_category = true;
  EscConfig c;
  c.name = cfg_.name;
  c.sii = build_sii(s);
  c.mailbox_out_start = kMailboxOut;
  c.mailbox_out_size = kMailboxSize;
  c.mailbox_in_start = kMailboxIn;
  c.mailbox_in_size = kMailboxSize;
  c.dc = true;
  c.drift_ppm = cfg_.drift_ppm;
  c.clock_at_power_on_ns = cfg_.clock_at_power_on_ns;
  return c;
}

uint32_t CoeDrive::check_mapping_write(const canopen::OdEntry& e, const uint8_t* d, std::size_t n) const {
  if (state_ != AlState::PreOp) return ab::kDeviceState;
  const uint16_t index = e.addr.index;
  if (index == 0x1C12 || index == 0x1C13) {
    if (e.addr.sub == 0) return d[0] > 2 ? ab::kValueRange : 0;
    const uint16_t base = index == 0x1C12 ? 0x1600 : 0x1A00;
    const uint16_t v = n >= 2 ? get16(d) : 0;
    return v == 0 || (v >= base && v < base + std::min<uint16_t>(cfg_.pdo_mappings, 32)) ? 0 : ab::kValueRange;
  }
  if (e.addr.sub == 0) return d[0] > 8 ? ab::kValueRange : 0;
  const auto m = canopen::PdoMapEntry::decode(n >= 4 ? get32(d) : 0);
  if (m.index == 0 && m.bits == 0) return 0;
  if (m.is_dummy()) return 0;
  const canopen::OdEntry* t = od_.find({m.index, m.sub});
  if (!t) return ab::kNoObject;
  if (!t->pdo_mappable) return ab::kNotMappable;
  if (m.bits != t->capacity * 8) return ab::kPdoLength;
  return 0;
}

uint32_t CoeDrive::build_map(uint16_t assign, std::vector<MapItem>& out, unsigned& bits) const {
  out.clear();
  bits = 0;
  const uint8_t pdos = od_.get<uint8_t>({assign, 0});
  for (uint8_t k = 1; k <= pdos; ++k) {
    const uint16_t pdo = od_.get<uint16_t>({assign, k});
    const uint8_t count = od_.get<uint8_t>({pdo, 0});
    for (uint8_t s = 1; s <= count; ++s) {
      const auto m = canopen::PdoMapEntry::decode(od_.get<uint32_t>({pdo, s}));
      MapItem it;
      it.bit = static_cast<uint16_t>(bits);
      it.bits = m.bits;
      if (m.is_dummy()) {
        it.dummy = true;
      } else {
        const canopen::OdEntry* t = od_.find({m.index, m.sub});
        if (!t || !t->pdo_mappable) return 1;
        it.od_offset = t->offset;
      }
      bits += m.bits;
      out.push_back(it);
    }
  }
  return 0;
}

uint16_t CoeDrive::check_transition(AlState from, AlState to, const Esc& esc) {
  if (from == AlState::PreOp && to == AlState::SafeOp) {
    if (build_map(0x1C12, rx_map_, rx_bits_) != 0) return al::kInvalidOutputMapping;
    if (build_map(0x1C13, tx_map_, tx_bits_) != 0) return al::kInvalidInputMapping;
    const SmEntry s2 = esc.sm(2), s3 = esc.sm(3);
    const unsigned out_bytes = (rx_bits_ + 7) / 8, in_bytes = (tx_bits_ + 7) / 8;
    if (out_bytes > 0 && (!s2.enabled() || s2.length != out_bytes || (s2.control & 0x0F) != 0x04)) {
      return al::kInvalidOutputConfig;
    }
    if (in_bytes > 0 && (!s3.enabled() || s3.length != in_bytes || (s3.control & 0x0F) != 0x00)) {
      return al::kInvalidInputConfig;
    }
    if (od_.get<uint16_t>({0x1C32, 1}) == 2) {
      if (!esc.sync0_active()) return al::kInvalidDcSync;
      const uint32_t cycle = od_.get<uint32_t>({0x1C32, 2});
      if (esc.sync0_cycle_ns() < 125'000 || (cycle != 0 && cycle != esc.sync0_cycle_ns())) return al::kInvalidDcCycle;
    }
  }
  return 0;
}

void CoeDrive::on_state(AlState from, AlState to, int64_t) {
  state_ = to;
  fresh_outputs_ = false;
  if (to == AlState::Init || to == AlState::PreOp) transfer_ = to == AlState::Init ? Transfer::None : transfer_;
  if (from == AlState::Op && to != AlState::Op && model_.state() == cia402::State::OperationEnabled) {
    model_.connection_lost(0x8100);  // left OP while enabled: no more set-points
  }
}

void CoeDrive::on_outputs(const uint8_t* data, std::size_t size, int64_t now_ns) noexcept {
  if (state_ != AlState::Op) return;
  uint8_t* storage = od_.data(od_.entries().front()) - od_.entries().front().offset;
  for (const MapItem& m : rx_map_) {
    if (m.dummy || (m.bit + m.bits + 7u) / 8u > size) continue;
    canopen::copy_bits(data, m.bit, storage + m.od_offset, 0, m.bits);
  }
  now_ns_ = now_ns;
  if (od_.get<uint16_t>({0x1C32, 1}) == 2) {  // DC SYNC0: applied at the next pulse
    if (fresh_outputs_) ++outputs_overwritten_;
    fresh_outputs_ = true;
    return;
  }
  model_.on_sync(now_ns);
}

void CoeDrive::on_sync0(int64_t t_ns) noexcept {
  if (state_ != AlState::Op || od_.get<uint16_t>({0x1C32, 1}) != 2) return;
  if (!fresh_outputs_) {
    ++sync_missed_;
    od_.set<uint16_t>({0x1C32, 0x0B}, static_cast<uint16_t>(sync_missed_));
  }
  fresh_outputs_ = false;
  if (t_ns > now_ns_) now_ns_ = t_ns;
  model_.on_sync(t_ns);
}

void CoeDrive::fill_inputs(uint8_t* data, std::size_t size) noexcept {
  if (state_ != AlState::SafeOp && state_ != AlState::Op) return;
  const uint8_t* storage = od_.data(od_.entries().front()) - od_.entries().front().offset;
  for (const MapItem& m : tx_map_) {
    if (m.dummy || (m.bit + m.bits + 7u) / 8u > size) continue;
    canopen::copy_bits(storage + m.od_offset, 0, data, m.bit, m.bits);
  }
}

void CoeDrive::on_watchdog(int64_t now_ns) noexcept {
  now_ns_ = now_ns;
  model_.advance_to(now_ns);
  model_.connection_lost(cia402::err::kRpdoTimeout);
}

void CoeDrive::poll(int64_t now_ns) noexcept {
  if (now_ns <= now_ns_) return;
  now_ns_ = now_ns;
  model_.advance_to(now_ns);
}

void CoeDrive::emergency(uint16_t code, uint8_t reg) {
  if (!esc_) return;
  uint8_t m[kMailboxHeader + 10] = {};
  MailboxHeader h;
  h.length = 10;
  h.type = MailboxType::CoE;
  counter_ = static_cast<uint8_t>(counter_ % 7 + 1);
  h.counter = counter_;
  h.encode(m);
  put16(m + 6, coe_header(CoeService::Emergency));
  put16(m + 8, code);
  m[10] = reg;
  esc_->post_mailbox(m, sizeof m);
}

void CoeDrive::reply(Esc& esc, const uint8_t* sdo, std::size_t n, CoeService service) {
  uint8_t m[kMailboxSize] = {};
  const std::size_t len = std::max<std::size_t>(2 + n, 10);
  MailboxHeader h;
  h.length = static_cast<uint16_t>(len);
  h.type = MailboxType::CoE;
  counter_ = static_cast<uint8_t>(counter_ % 7 + 1);
  h.counter = counter_;
  h.encode(m);
  put16(m + 6, coe_header(service));
  last_reply_service_ = service;
  std::memcpy(m + 8, sdo, std::min<std::size_t>(n, sizeof m - 8));
  esc.post_mailbox(m, kMailboxHeader + len);
}

void CoeDrive::abort(Esc& esc, uint16_t index, uint8_t sub, uint32_t code) {
  transfer_ = Transfer::None;
  uint8_t s[8] = {0x80};
  put16(s + 1, index);
  s[3] = sub;
  put32(s + 4, code);
  // IEC 61158-6-12 (Abort SDO Transfer): the abort travels as an SDO
  // *request* (CoE service 2), from either side; masters match on it.
  reply(esc, s, 8, CoeService::SdoRequest);
}

void CoeDrive::on_mailbox(const uint8_t* data, std::size_t size, Esc& esc, int64_t now_ns) {
  esc_ = &esc;
  now_ns_ = std::max(now_ns_, now_ns);
  const MailboxHeader h = MailboxHeader::decode(data);
  auto mailbox_error = [&](uint16_t detail) {
    uint8_t m[kMailboxHeader + 4] = {};
    MailboxHeader e;
    e.length = 4;
    e.type = MailboxType::Error;
    e.encode(m);
    put16(m + 6, 0x01);  // service: mailbox error
    put16(m + 8, detail);
    esc.post_mailbox(m, sizeof m);
  };
  if (h.length + kMailboxHeader > size || h.length < 2) return mailbox_error(8);
  if (h.type != MailboxType::CoE) return mailbox_error(2);
  const uint8_t* coe = data + kMailboxHeader;
  const CoeService service = coe_service(get16(coe));
  if (service == CoeService::SdoInfo) return sdo_info(coe + 2, h.length - 2, esc);
  if (service != CoeService::SdoRequest) return mailbox_error(4);
  sdo(coe + 2, h.length - 2, esc);
}

// SDO information (CoE service 8): header opcode (bit 7: more fragments
// follow), reserved, fragments left U16; then the opcode's data.
void CoeDrive::info_reply(Esc& esc, uint8_t opcode, const std::vector<uint8_t>& payload) {
  constexpr std::size_t kRoom = kMailboxSize - kMailboxHeader - 2 - 4;
  const std::size_t fragments = payload.empty() ? 1 : (payload.size() + kRoom - 1) / kRoom;
  for (std::size_t f = 0; f < fragments; ++f) {
    const std::size_t off = f * kRoom;
    const std::size_t n = std::min(kRoom, payload.size() - std::min(payload.size(), off));
    uint8_t m[kMailboxSize] = {};
    MailboxHeader h;
    h.length = static_cast<uint16_t>(2 + 4 + n);
    h.type = MailboxType::CoE;
    counter_ = static_cast<uint8_t>(counter_ % 7 + 1);
    h.counter = counter_;
    h.encode(m);
    put16(m + 6, coe_header(CoeService::SdoInfo));
    m[8] = static_cast<uint8_t>(opcode | (f + 1 < fragments ? 0x80 : 0));
    put16(m + 10, static_cast<uint16_t>(fragments - 1 - f));
    if (n) std::memcpy(m + 12, payload.data() + off, n);
    esc.post_mailbox(m, kMailboxHeader + h.length);
  }
}

void CoeDrive::sdo_info(const uint8_t* d, std::size_t n, Esc& esc) {
  auto error = [&](uint32_t code) {
    std::vector<uint8_t> p(4);
    put32(p.data(), code);
    info_reply(esc, 7, p);
  };
  if (n < 4) return error(ab::kCommandSpecifier);
  const uint8_t opcode = d[0] & 0x7F;
  const uint8_t* q = d + 4;
  const std::size_t qn = n - 4;
  std::vector<uint8_t> p;
  auto put_u16 = [&](uint16_t v) { p.push_back(static_cast<uint8_t>(v)), p.push_back(static_cast<uint8_t>(v >> 8)); };
  if (opcode == 1) {  // OD list
    const uint16_t type = qn >= 2 ? get16(q) : 1;
    if (type != 1) return error(ab::kUnsupportedAccess);  // only "all objects"
    put_u16(type);
    uint16_t last = 0;
    bool any = false;
    for (const canopen::OdEntry& e : od_.entries()) {
      if (any && e.addr.index == last) continue;
      put_u16(e.addr.index);
      last = e.addr.index;
      any = true;
    }
    return info_reply(esc, 2, p);
  }
  if (opcode == 3 && qn >= 2) {  // object description
    const uint16_t index = get16(q);
    const canopen::OdEntry* first = nullptr;
    uint8_t max_sub = 0;
    for (const canopen::OdEntry& e : od_.entries()) {
      if (e.addr.index != index) continue;
      if (!first) first = &e;
      max_sub = std::max(max_sub, e.addr.sub);
    }
    if (!first) return error(ab::kNoObject);
    put_u16(index);
    put_u16(static_cast<uint16_t>(first->type));
    p.push_back(max_sub);
    p.push_back(max_sub == 0 ? 7 : 9);  // VAR or RECORD
    p.insert(p.end(), first->name.begin(), first->name.end());
    return info_reply(esc, 4, p);
  }
  if (opcode == 5 && qn >= 4) {  // entry description
    const canopen::OdEntry* e = od_.find({get16(q), q[2]});
    if (!e) return error(od_.has_index(get16(q)) ? ab::kNoSubIndex : ab::kNoObject);
    put_u16(e->addr.index);
    p.push_back(e->addr.sub);
    p.push_back(q[3]);
    put_u16(static_cast<uint16_t>(e->type));
    put_u16(static_cast<uint16_t>(e->capacity * 8));
    uint16_t access = 0;
    if (canopen::is_readable(e->access)) access |= 0x07;
    if (canopen::is_writable(e->access)) access |= 0x38;
    if (e->pdo_mappable) access |= canopen::is_writable(e->access) ? 0x40 : 0x80;
    put_u16(access);
    p.insert(p.end(), e->name.begin(), e->name.end());
    return info_reply(esc, 6, p);
  }
  error(ab::kCommandSpecifier);
}

uint32_t CoeDrive::finish_download(const uint8_t* data, std::size_t n) {
  if (!t_complete_) return od_.write({t_index_, t_sub_}, data, n, true);
  return unpack_complete(t_index_, t_sub_, std::vector<uint8_t>(data, data + n));
}

uint32_t CoeDrive::pack_complete(uint16_t index, uint8_t sub, std::vector<uint8_t>& out) {
  out.clear();
  if (!od_.has_index(index)) return ab::kNoObject;
  uint8_t tmp[64];
  const uint8_t count = od_.get<uint8_t>({index, 0});  // sub-indices 1..count are in use
  for (const canopen::OdEntry& e : od_.entries()) {
    if (e.addr.index != index || e.addr.sub < sub || (e.addr.sub > 0 && e.addr.sub > count)) continue;
    std::size_t n = 0;
    if (const uint32_t a = od_.read(e.addr, tmp, sizeof tmp, n, true)) return a;
    out.insert(out.end(), tmp, tmp + n);
    if (e.addr.sub == 0) out.push_back(0);  // sub-index 0 takes 16 bits
  }
  return 0;
}

uint32_t CoeDrive::unpack_complete(uint16_t index, uint8_t sub, const std::vector<uint8_t>& in) {
  if (!od_.has_index(index)) return ab::kNoObject;
  std::size_t pos = 0;
  uint8_t count = od_.get<uint8_t>({index, 0});
  if (sub == 0) {
    if (in.size() < 2) return ab::kLengthTooLow;
    count = in[0];
    pos = 2;
    const uint8_t zero = 0;
    if (const uint32_t a = od_.write({index, 0}, &zero, 1, true)) return a;  // entries change under count 0
  }
  for (uint8_t k = 1; k <= count; ++k) {
    const canopen::OdEntry* e = od_.find({index, k});
    if (!e) return ab::kNoSubIndex;
    if (pos + e->capacity > in.size()) return ab::kLengthTooLow;
    if (const uint32_t a = od_.write(e->addr, in.data() + pos, e->capacity, true)) return a;
    pos += e->capacity;
  }
  if (pos != in.size()) return ab::kLengthTooHigh;
  if (sub == 0) return od_.write({index, 0}, &count, 1, true);
  return 0;
}

void CoeDrive::sdo(const uint8_t* d, std::size_t n, Esc& esc) {
  ++sdo_requests_;
  if (n < 8) return abort(esc, 0, 0, ab::kCommandSpecifier);
  const uint8_t cmd = d[0];
  const uint8_t ccs = cmd >> 5;
  uint16_t index = get16(d + 1);
  uint8_t sub = d[3];
  if (ccs == 0 || ccs == 3) {  // segments continue the transfer in progress
    index = t_index_;
    sub = t_sub_;
  }
  if (abort_code_ != 0 && index == abort_index_) return abort(esc, index, sub, abort_code_);
  if (ccs == 1 || ccs == 2) {
    t_complete_ = (cmd & 0x10) != 0;  // complete access
    if (t_complete_ && sub > 1) return abort(esc, index, sub, ab::kUnsupportedAccess);
  }
  switch (ccs) {
    case 1: {  // initiate download
      const bool expedited = cmd & 0x02;
      if (expedited) {
        const std::size_t len = (cmd & 0x01) ? 4u - ((cmd >> 2) & 3u) : 4u;
        t_index_ = index;
        t_sub_ = sub;
        if (const uint32_t a = finish_download(d + 4, len)) return abort(esc, index, sub, a);
        uint8_t r[8] = {0x60};
        put16(r + 1, index);
        r[3] = sub;
        return reply(esc, r, 8);
      }
      const std::size_t total = get32(d + 4);
      const std::size_t here = std::min(total, n - 8);
      if (total > od_.max_capacity() * (t_complete_ ? 64 : 1)) return abort(esc, index, sub, ab::kLengthTooHigh);
      buffer_.assign(d + 8, d + 8 + here);
      t_index_ = index;
      t_sub_ = sub;
      t_size_ = total;
      toggle_ = 0;
      if (here == total) {
        transfer_ = Transfer::None;
        if (const uint32_t a = finish_download(buffer_.data(), total)) return abort(esc, index, sub, a);
      } else {
        transfer_ = Transfer::Download;
      }
      uint8_t r[8] = {0x60};
      put16(r + 1, index);
      r[3] = sub;
      return reply(esc, r, 8);
    }
    case 0: {  // download segment
      if (transfer_ != Transfer::Download) return abort(esc, index, sub, ab::kCommandSpecifier);
      if (((cmd >> 4) & 1) != toggle_) return abort(esc, index, sub, ab::kToggleBit);
      const std::size_t unused = (cmd >> 1) & 7;
      const std::size_t len = (n - 1) > 7 ? n - 1 : 7 - unused;
      buffer_.insert(buffer_.end(), d + 1, d + 1 + std::min(len, n - 1));
      const bool last = cmd & 1;
      uint8_t r[8] = {static_cast<uint8_t>(0x20 | (toggle_ << 4))};
      toggle_ ^= 1;
      if (buffer_.size() > t_size_) return abort(esc, index, sub, ab::kLengthTooHigh);
      if (last) {
        transfer_ = Transfer::None;
        if (buffer_.size() != t_size_) return abort(esc, index, sub, ab::kLengthTooLow);
        if (const uint32_t a = finish_download(buffer_.data(), buffer_.size())) return abort(esc, index, sub, a);
      }
      return reply(esc, r, 8);
    }
    case 2: {  // initiate upload
      std::size_t len = 0;
      if (t_complete_) {
        if (const uint32_t a = pack_complete(index, sub, buffer_)) return abort(esc, index, sub, a);
        len = buffer_.size();
      } else {
        buffer_.resize(od_.max_capacity());
        if (const uint32_t a = od_.read({index, sub}, buffer_.data(), buffer_.size(), len, true)) {
          return abort(esc, index, sub, a);
        }
        buffer_.resize(len);
      }
      if (len <= 4) {
        uint8_t r[8] = {static_cast<uint8_t>(0x43 | ((4 - len) << 2))};
        put16(r + 1, index);
        r[3] = sub;
        std::memcpy(r + 4, buffer_.data(), len);
        transfer_ = Transfer::None;
        return reply(esc, r, 8);
      }
      const std::size_t room = kMailboxSize - kMailboxHeader - 2 - 8;
      const std::size_t here = std::min(len, room);
      uint8_t r[kMailboxSize] = {0x41};
      put16(r + 1, index);
      r[3] = sub;
      put32(r + 4, static_cast<uint32_t>(len));
      std::memcpy(r + 8, buffer_.data(), here);
      t_index_ = index;
      t_sub_ = sub;
      t_size_ = len;
      t_pos_ = here;
      toggle_ = 0;
      transfer_ = here < len ? Transfer::Upload : Transfer::None;
      return reply(esc, r, 8 + here);
    }
    case 3: {  // upload segment
      if (transfer_ != Transfer::Upload) return abort(esc, index, sub, ab::kCommandSpecifier);
      if (((cmd >> 4) & 1) != toggle_) return abort(esc, index, sub, ab::kToggleBit);
      const std::size_t room = kMailboxSize - kMailboxHeader - 2 - 1;
      const std::size_t here = std::min(t_size_ - t_pos_, room);
      const bool last = t_pos_ + here == t_size_;
      uint8_t r[kMailboxSize] = {};
      r[0] = static_cast<uint8_t>((toggle_ << 4) | (last ? 1 : 0) | (here < 7 ? (7 - here) << 1 : 0));
      std::memcpy(r + 1, buffer_.data() + t_pos_, here);
      t_pos_ += here;
      toggle_ ^= 1;
      if (last) transfer_ = Transfer::None;
      return reply(esc, r, std::max<std::size_t>(1 + here, 8));
    }
    case 4:  // abort from the master
      transfer_ = Transfer::None;
      return;
    default:
      return abort(esc, index, sub, ab::kCommandSpecifier);
  }
}

}  // namespace cnc::ethercat::sim
