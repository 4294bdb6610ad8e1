#include "fieldbus/ethercat/cia402_binding.hpp"

#include "fieldbus/ethercat/master.hpp"

namespace cnc::ethercat {
namespace {

class EthercatLink final : public cia402::DriveLink {
 public:
  explicit EthercatLink(Master& m) : m_(m) {}

  const std::string& name() const noexcept override { return m_.name(); }
  // h.lost below is the bus's fault: the safe stop after MISS_LIMIT cycles
  // without valid process data, or a slave that left OP.
  const char* loss_causes() const noexcept override {
    return "process data lost (frames lost or working-counter errors) or a slave left OP";
  }
  bool has_device(int a) const noexcept override {
    if (a < 1) return false;
    if (m_.slave_count() > 0) return static_cast<std::size_t>(a) <= m_.slave_count();  // scanned
    return m_.config().slaves.empty() || m_.config().slave(static_cast<unsigned>(a)) != nullptr;
  }
  cia402::Slot output(int a, cia402::Object o) const noexcept override {
    return m_.output(static_cast<unsigned>(a), o.index, o.sub);
  }
  cia402::Slot input(int a, cia402::Object o) const noexcept override {
    return m_.input(static_cast<unsigned>(a), o.index, o.sub);
  }
  cia402::ConfigResult read_wait(int a, cia402::Object o, unsigned size) override {
    const SdoResult r = m_.sdo_upload(static_cast<unsigned>(a), o.index, o.sub);
    cia402::ConfigResult out;
    out.ok = r.ok;
    out.abort_code = r.abort_code;
    if (!r.ok) out.text = "CoE SDO upload failed: " + r.error;
    for (std::size_t i = 0; i < r.data.size() && i < 8 && i < size; ++i) out.value |= uint64_t{r.data[i]} << (8 * i);
    return out;
  }
  cia402::ConfigResult write_wait(int a, cia402::Object o, uint64_t value, unsigned size) override {
    std::vector<uint8_t> d(size);
    for (unsigned i = 0; i < size; ++i) d[i] = static_cast<uint8_t>(value >> (8 * i));
    const SdoResult r = m_.sdo_download(static_cast<unsigned>(a), o.index, o.sub, d);
    cia402::ConfigResult out;
    out.ok = r.ok;
    out.abort_code = r.abort_code;
    if (!r.ok) out.text = "CoE SDO download failed: " + r.error;
    return out;
  }
  int64_t cycle_ns() const noexcept override { return m_.config().cycle_ns; }

  cia402::LinkHealth health(int a) const noexcept override {
    cia402::LinkHealth h;
    const auto p = static_cast<unsigned>(a);
    const uint8_t al = m_.slave_al_state(p);
    h.operational = m_.is_operational() && al == static_cast<uint8_t>(AlState::Op);
    h.inputs_fresh = m_.counters().inputs_fresh.load(std::memory_order_relaxed);
    h.lost = m_.has_fault();
    h.emcy_code = m_.slave_emcy_code(p);
    h.emcy_count = m_.slave_emcy_count(p);
    return h;
  }
  int request_read(int a, cia402::Object o) noexcept override {
    return m_.rt_sdo_read(static_cast<unsigned>(a), o.index, o.sub);
  }
  int request_write(int a, cia402::Object o, uint32_t value, unsigned size) noexcept override {
    return m_.rt_sdo_write(static_cast<unsigned>(a), o.index, o.sub, value, static_cast<uint8_t>(size));
  }
  bool poll(int handle, cia402::AcyclicResult& out) noexcept override {
    return m_.rt_sdo_poll(handle, out.abort_code, out.value);
  }

 private:
  Master& m_;
};

}  // namespace

std::unique_ptr<cia402::DriveLink> make_cia402_link(Master& master) { return std::make_unique<EthercatLink>(master); }

}  // namespace cnc::ethercat
