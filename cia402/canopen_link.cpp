#include "cia402/canopen_link.hpp"

#include <array>
#include <stdexcept>
#include <vector>

#include "fieldbus/canopen/components.hpp"
#include "fieldbus/canopen/master.hpp"

namespace cnc::cia402 {
namespace {

canopen::ObjectAddress addr(Object o) { return canopen::ObjectAddress{o.index, o.sub}; }
Slot slot(const canopen::PdoSlot& s) { return Slot{s.bytes, s.bit_offset, s.bit_length}; }

class CanopenLink final : public DriveLink {
 public:
  explicit CanopenLink(canopen::Master& m) : m_(m) {}

  const std::string& name() const noexcept override { return m_.name(); }
  bool has_device(int address) const noexcept override {
    return address >= 1 && address <= 127 && m_.config().node(static_cast<uint8_t>(address)) != nullptr;
  }
  Slot output(int a, Object o) const noexcept override {
    return slot(m_.output(static_cast<uint8_t>(a), o.index, o.sub));
  }
  Slot input(int a, Object o) const noexcept override {
    return slot(m_.input(static_cast<uint8_t>(a), o.index, o.sub));
  }
  ConfigResult read_wait(int a, Object o, unsigned size) override {
    const canopen::SdoResult r = m_.sdo_upload_wait(static_cast<uint8_t>(a), addr(o));
    ConfigResult out;
    out.ok = r.ok();
    out.abort_code = r.abort_code;
    if (!r.ok()) out.text = r.message();
    for (std::size_t i = 0; i < r.data.size() && i < 8 && i < size; ++i) out.value |= uint64_t{r.data[i]} << (8 * i);
    return out;
  }
  ConfigResult write_wait(int a, Object o, uint64_t value, unsigned size) override {
    std::vector<uint8_t> data(size);
    for (unsigned i = 0; i < size; ++i) data[i] = static_cast<uint8_t>(value >> (8 * i));
    const canopen::SdoResult r = m_.sdo_download_wait(static_cast<uint8_t>(a), addr(o), std::move(data));
    ConfigResult out;
    out.ok = r.ok();
    out.abort_code = r.abort_code;
    if (!r.ok()) out.text = r.message();
    return out;
  }
  int64_t cycle_ns() const noexcept override { return m_.config().cycle_ns; }

  LinkHealth health(int a) const noexcept override {
    const canopen::NodeStatus s = m_.node_status(static_cast<uint8_t>(a));
    LinkHealth h;
    h.operational = s.operational && m_.is_cyclic_running();
    h.lost = s.heartbeat_lost || (s.booted && s.state != canopen::NmtState::Operational);
    h.emcy_code = s.emcy_code;
    h.emcy_count = s.emcy_count;
    // Fresh when no synchronous TPDO of the node missed the last SYNC.
    const std::size_t i = static_cast<std::size_t>(a) & 0x7F;
    h.inputs_fresh = s.pdo_missed == last_missed_[i] && m_.cyclic_status().sync_serial > 1;
    last_missed_[i] = s.pdo_missed;
    return h;
  }
  int request_read(int a, Object o) noexcept override { return m_.rt_sdo_read(static_cast<uint8_t>(a), addr(o)); }
  int request_write(int a, Object o, uint32_t value, unsigned size) noexcept override {
    return m_.rt_sdo_write(static_cast<uint8_t>(a), addr(o), value, static_cast<uint8_t>(size));
  }
  bool poll(int handle, AcyclicResult& out) noexcept override {
    canopen::RtSdoResult r;
    if (!m_.rt_sdo_poll(handle, r)) return false;
    out.abort_code = r.abort_code;
    out.value = r.value;
    return true;
  }

 private:
  canopen::Master& m_;
  mutable std::array<uint32_t, 128> last_missed_{};
};

}  // namespace

std::unique_ptr<DriveLink> make_canopen_link(canopen::Master& master) { return std::make_unique<CanopenLink>(master); }

namespace {
std::vector<LinkFinder>& finders() {
  static std::vector<LinkFinder> f;
  return f;
}
}  // namespace

void register_link_finder(LinkFinder finder) {
  for (LinkFinder f : finders()) {
    if (f == finder) return;
  }
  finders().push_back(finder);
}

std::unique_ptr<DriveLink> find_link(hal::Hal& hal, const std::string& bus) {
  if (canopen::Master* m = canopen::find_master(hal, bus)) return make_canopen_link(*m);
  for (LinkFinder f : finders()) {
    if (auto link = f(hal, bus)) return link;
  }
  throw std::runtime_error("no fieldbus \"" + bus + "\" is loaded (loadrt canopen or ethercat before loadrt cia402)");
}

}  // namespace cnc::cia402
