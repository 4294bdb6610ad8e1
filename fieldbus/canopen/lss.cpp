#include "fieldbus/canopen/lss.hpp"

#include <cstdio>
#include <stdexcept>

namespace cnc::canopen::lss {

namespace {

uint32_t u32(const can::Frame& f, int at) noexcept {
  return static_cast<uint32_t>(f.data[at]) | static_cast<uint32_t>(f.data[at + 1]) << 8 |
         static_cast<uint32_t>(f.data[at + 2]) << 16 | static_cast<uint32_t>(f.data[at + 3]) << 24;
}

can::Frame answer(std::initializer_list<uint8_t> bytes) noexcept {
  can::Frame f = can::Frame::make(kSlaveCob, bytes);
  f.len = 8;  // LSS frames are always 8 bytes, unused ones 0
  return f;
}

can::Frame answer_u32(uint8_t cs, uint32_t v) noexcept {
  return answer({cs, static_cast<uint8_t>(v), static_cast<uint8_t>(v >> 8), static_cast<uint8_t>(v >> 16),
                 static_cast<uint8_t>(v >> 24)});
}

// Bit rates of CiA 305's table 0, by index (0: reserved / automatic).
constexpr std::array<uint32_t, 10> kTable0 = {1'000'000, 800'000, 500'000, 250'000, 125'000, 0, 50'000, 20'000, 10'000, 0};

}  // namespace

std::string to_string(const Address& a) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "vendor 0x%08X product 0x%08X revision 0x%08X serial 0x%08X", a.vendor, a.product,
                a.revision, a.serial);
  return buf;
}

uint32_t bitrate_of_index(uint8_t index) noexcept { return index < kTable0.size() ? kTable0[index] : 0; }

std::optional<uint8_t> index_of_bitrate(uint32_t bitrate) noexcept {
  for (std::size_t i = 0; i < kTable0.size(); ++i) {
    if (kTable0[i] != 0 && kTable0[i] == bitrate) return static_cast<uint8_t>(i);
  }
  return std::nullopt;
}

// --- device side ---

bool Slave::take_node_id_change(uint8_t& new_id) noexcept {
  if (!change_) return false;
  change_ = false;
  new_id = active_;
  return true;
}

bool Slave::on_frame(const can::Frame& f, can::Frame& reply) noexcept {
  if (f.id != kMasterCob || f.is_remote() || f.is_extended() || f.len < 8) return false;
  const uint8_t cs = f.data[0];
  // Selective switching is a sequence of four frames; anything else in
  // between starts it over.
  if (cs < kSwitchSelectiveVendor || cs > kSwitchSelectiveSerial) selective_ = 0;
  switch (cs) {
    case kSwitchGlobal:
      if (f.data[1] == 1) {
        mode_ = Mode::Configuration;
      } else if (f.data[1] == 0) {
        // Back to waiting: an unconfigured device that was given a node-ID
        // takes it now (CiA 305 §6.3.2); a configured one at its next reset.
        if (mode_ == Mode::Configuration && active_ == kUnconfigured && pending_ != kUnconfigured) {
          active_ = pending_;
          change_ = true;
        }
        mode_ = Mode::Waiting;
      }
      return false;
    case kSwitchSelectiveVendor:
    case kSwitchSelectiveProduct:
    case kSwitchSelectiveRevision:
    case kSwitchSelectiveSerial: {
      const int part = cs - kSwitchSelectiveVendor;
      if (part != selective_ || u32(f, 1) != address_.part(part)) {
        selective_ = 0;
        return false;
      }
      if (++selective_ < 4) return false;
      selective_ = 0;
      mode_ = Mode::Configuration;
      reply = answer({kSwitchSelectiveResponse});
      return true;
    }
    case kConfigureNodeId: {
      if (mode_ != Mode::Configuration) return false;
      const uint8_t id = f.data[1];
      const bool ok = (id >= 1 && id <= 127) || id == kUnconfigured;
      if (ok) pending_ = id;
      reply = answer({kConfigureNodeId, static_cast<uint8_t>(ok ? 0 : 1)});
      return true;
    }
    case kConfigureBitTiming: {
      if (mode_ != Mode::Configuration) return false;
      const bool ok = f.data[1] == 0 && bitrate_of_index(f.data[2]) != 0;
      if (ok) bit_timing_ = f.data[2];
      reply = answer({kConfigureBitTiming, static_cast<uint8_t>(ok ? 0 : 1)});
      return true;
    }
    case kActivateBitTiming:
      return false;  // a simulated device has no bit timing to switch
    case kStoreConfiguration:
      if (mode_ != Mode::Configuration) return false;
      stored_ = pending_;
      ++stores_;
      reply = answer({kStoreConfiguration, 0});
      return true;
    case kInquireVendor:
    case kInquireProduct:
    case kInquireRevision:
    case kInquireSerial:
      if (mode_ != Mode::Configuration) return false;
      reply = answer_u32(cs, address_.part(cs - kInquireVendor));
      return true;
    case kInquireNodeId:
      if (mode_ != Mode::Configuration) return false;
      reply = answer({kInquireNodeId, active_});
      return true;
    case kFastscan: {
      // Only devices without a node-ID, in waiting mode, take part.
      if (mode_ != Mode::Waiting || active_ != kUnconfigured) return false;
      const uint32_t id = u32(f, 1);
      const uint8_t bit_check = f.data[5], sub = f.data[6], next = f.data[7];
      if (bit_check == 0x80) {  // "is anybody there?": restart
        fastscan_pos_ = 0;
        reply = answer({kIdentifySlave});
        return true;
      }
      if (bit_check > 31 || sub > 3 || next > 3 || sub != fastscan_pos_) return false;
      const uint32_t mask = bit_check == 0 ? 0xFFFFFFFFu : ~((1u << bit_check) - 1u);
      if (((id ^ address_.part(sub)) & mask) != 0) return false;
      if (bit_check == 0) {
        // The whole value confirmed: on to the next part, and after the
        // serial number into configuration mode.
        if (sub == 3) {
          mode_ = Mode::Configuration;
          fastscan_pos_ = 0;
        } else {
          fastscan_pos_ = next;
        }
      }
      reply = answer({kIdentifySlave});
      return true;
    }
    default:
      return false;
  }
}

// --- master side ---

void Master::send(std::initializer_list<uint8_t> bytes) {
  // Several devices answer one request (each fastscan step, a switch
  // global): the answers to the last request are dropped so that they are
  // not taken for answers to this one.
  can::Frame stale;
  while (bus_.receive(stale)) {
  }
  can::Frame f = can::Frame::make(kMasterCob, bytes);
  f.len = 8;
  const can::SendStatus s = bus_.send(f);
  if (s != can::SendStatus::Ok) {
    throw std::runtime_error("LSS: cannot send on " + bus_.name() + ": " + can::to_string(s));
  }
  ++sent_;
}

void Master::send_u32(uint8_t cs, uint32_t v, uint8_t b5, uint8_t b6, uint8_t b7) {
  send({cs, static_cast<uint8_t>(v), static_cast<uint8_t>(v >> 8), static_cast<uint8_t>(v >> 16),
        static_cast<uint8_t>(v >> 24), b5, b6, b7});
}

std::optional<can::Frame> Master::wait_for(uint8_t cs) {
  const int64_t deadline = bus_.now_ns() + timeout_ns_;
  for (;;) {
    can::Frame f;
    while (bus_.receive(f)) {
      if (!f.is_error() && !f.is_extended() && !f.is_remote() && f.id == kSlaveCob && f.len >= 1 && f.data[0] == cs) {
        return f;
      }
    }
    const int64_t left = deadline - bus_.now_ns();
    if (left <= 0) return std::nullopt;
    bus_.wait(left < 1'000'000 ? left : 1'000'000);
  }
}

bool Master::switch_global(bool configuration) {
  send({kSwitchGlobal, static_cast<uint8_t>(configuration ? 1 : 0)});
  return true;
}

bool Master::switch_selective(const Address& a) {
  for (int i = 0; i < 4; ++i) send_u32(static_cast<uint8_t>(kSwitchSelectiveVendor + i), a.part(i));
  return wait_for(kSwitchSelectiveResponse).has_value();
}

void Master::configure_node_id(uint8_t id) {
  send({kConfigureNodeId, id});
  const auto r = wait_for(kConfigureNodeId);
  if (!r) throw std::runtime_error("LSS: no device answered 'configure node-ID " + std::to_string(id) + "'");
  if (r->data[1] != 0) {
    throw std::runtime_error("LSS: the device refused node-ID " + std::to_string(id) + " (error " +
                             std::to_string(r->data[1]) + ": out of range)");
  }
}

void Master::configure_bit_timing(uint32_t bitrate) {
  const auto index = index_of_bitrate(bitrate);
  if (!index) throw std::runtime_error("LSS: " + std::to_string(bitrate) + " bit/s is not in CiA 305's table");
  send({kConfigureBitTiming, 0, *index});
  const auto r = wait_for(kConfigureBitTiming);
  if (!r) throw std::runtime_error("LSS: no device answered 'configure bit timing'");
  if (r->data[1] != 0) throw std::runtime_error("LSS: the device refused " + std::to_string(bitrate) + " bit/s");
}

void Master::store() {
  send({kStoreConfiguration});
  const auto r = wait_for(kStoreConfiguration);
  if (!r) throw std::runtime_error("LSS: no device answered 'store configuration'");
  if (r->data[1] != 0) {
    throw std::runtime_error(std::string("LSS: the device could not store its configuration (") +
                             (r->data[1] == 1 ? "not supported" : "storage error") + ")");
  }
}

std::optional<uint32_t> Master::inquire(Cs what) {
  send({what});
  const auto r = wait_for(what);
  if (!r) return std::nullopt;
  if (what == kInquireNodeId) return r->data[1];
  return u32(*r, 1);
}

std::optional<Address> Master::inquire_address() {
  Address a;
  for (int i = 0; i < 4; ++i) {
    const auto v = inquire(static_cast<Cs>(kInquireVendor + i));
    if (!v) return std::nullopt;
    (i == 0 ? a.vendor : i == 1 ? a.product : i == 2 ? a.revision : a.serial) = *v;
  }
  return a;
}

bool Master::fastscan_step(uint32_t id, uint8_t bit_check, uint8_t sub, uint8_t next) {
  send_u32(kFastscan, id, bit_check, sub, next);
  // Every device that matches answers, and on the bus their answers come
  // one after the other: the whole window is waited for, so that no answer
  // to this step is taken for one to the next.
  const int64_t end = bus_.now_ns() + window_ns_;
  bool answered = false;
  for (;;) {
    can::Frame f;
    while (bus_.receive(f)) {
      if (!f.is_error() && !f.is_extended() && !f.is_remote() && f.id == kSlaveCob && f.len >= 1 &&
          f.data[0] == kIdentifySlave) {
        answered = true;
      }
    }
    const int64_t left = end - bus_.now_ns();
    if (left <= 0) return answered;
    bus_.wait(left < 1'000'000 ? left : 1'000'000);
  }
}

bool Master::any_unconfigured() { return fastscan_step(0, 0x80, 0, 0); }

std::optional<Address> Master::fastscan() {
  try {
    return fastscan_once();
  } catch (const std::runtime_error&) {
    // Once more from the start (a device late to answer one step); the
    // second failure is reported.
    return fastscan_once();
  }
}

std::optional<Address> Master::fastscan_once() {
  if (!any_unconfigured()) return std::nullopt;
  Address a;
  for (uint8_t sub = 0; sub < 4; ++sub) {
    uint32_t v = 0;
    // Bit by bit from the top: with bit b sent as 0, an answer means some
    // device has 0 there (and the bits above as found); silence means 1.
    for (int b = 31; b >= 1; --b) {
      if (!fastscan_step(v, static_cast<uint8_t>(b), sub, sub)) v |= 1u << b;
    }
    // Bit 0 and the confirmation of the whole value in one: the device
    // whose value it is moves on to the next part.
    const uint8_t next = static_cast<uint8_t>((sub + 1) % 4);
    if (!fastscan_step(v, 0, sub, next)) {
      v |= 1u;
      if (!fastscan_step(v, 0, sub, next)) {
        throw std::runtime_error("LSS fastscan: no device confirmed part " + std::to_string(sub) +
                                 " of its address (a device answering later than the step window of " +
                                 std::to_string(window_ns_ / 1'000'000) + " ms, or one that left the bus)");
      }
    }
    (sub == 0 ? a.vendor : sub == 1 ? a.product : sub == 2 ? a.revision : a.serial) = v;
  }
  return a;
}

}  // namespace cnc::canopen::lss
