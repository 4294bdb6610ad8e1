#include "fieldbus/canopen/cia402_binding.hpp"

#include <array>
#include <vector>

#include "fieldbus/canopen/master.hpp"

namespace cnc::canopen {
namespace {

using cia402::AcyclicResult;
using cia402::ConfigResult;
using cia402::LinkHealth;
using cia402::Object;
using cia402::Slot;

ObjectAddress addr(Object o) { return ObjectAddress{o.index, o.sub}; }

class CanopenLink final : public cia402::DriveLink {
 public:
  explicit CanopenLink(Master& m) : m_(m) {}

  const std::string& name() const noexcept override { return m_.name(); }
  const char* loss_causes() const noexcept override { return "heartbeat lost, reset, or no longer operational"; }
  bool has_device(int address) const noexcept override {
    return address >= 1 && address <= 127 && m_.config().node(static_cast<uint8_t>(address)) != nullptr;
  }
  Slot output(int a, Object o) const noexcept override {
    return m_.output(static_cast<uint8_t>(a), o.index, o.sub);
  }
  Slot input(int a, Object o) const noexcept override {
    return m_.input(static_cast<uint8_t>(a), o.index, o.sub);
  }
  uint64_t input_sequence(const Slot& s) const noexcept override { return m_.input_sequence(s); }
  ConfigResult read_wait(int a, Object o, unsigned size) override {
    const SdoResult r = m_.sdo_upload_wait(static_cast<uint8_t>(a), addr(o));
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
    const SdoResult r = m_.sdo_download_wait(static_cast<uint8_t>(a), addr(o), std::move(data));
    ConfigResult out;
    out.ok = r.ok();
    out.abort_code = r.abort_code;
    if (!r.ok()) out.text = r.message();
    return out;
  }
  int64_t cycle_ns() const noexcept override { return m_.config().cycle_ns; }

  LinkHealth health(int a) const noexcept override {
    const NodeStatus s = m_.node_status(static_cast<uint8_t>(a));
    LinkHealth h;
    h.operational = s.operational && m_.is_cyclic_running();
    h.lost = s.heartbeat_lost || (s.booted && s.state != NmtState::Operational);
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
    RtSdoResult r;
    if (!m_.rt_sdo_poll(handle, r)) return false;
    out.abort_code = r.abort_code;
    out.value = r.value;
    return true;
  }

 private:
  Master& m_;
  mutable std::array<uint32_t, 128> last_missed_{};
};

}  // namespace

std::unique_ptr<cia402::DriveLink> make_cia402_link(Master& master) { return std::make_unique<CanopenLink>(master); }

}  // namespace cnc::canopen
