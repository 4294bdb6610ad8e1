#include "commission/lss_assign.hpp"

#include <stdexcept>

namespace cnc::commission {

namespace lss = canopen::lss;

bool unconfigured_devices_present(can::Transport& bus, int64_t window_ns) {
  lss::Master m(bus, window_ns, window_ns);
  return m.any_unconfigured();
}

std::string describe(const LssAssignment& a) {
  return lss::to_string(a.address) + " -> node-ID " + std::to_string(a.node_id);
}

LssResult assign_node_ids(can::Transport& bus, const LssOptions& o) {
  LssResult r;
  lss::Master m(bus, o.timeout_ns, o.window_ns);
  int next = o.first;
  auto free_id = [&] {
    while (next <= 127 && o.taken.count(next)) ++next;
    return next;
  };
  for (int n = 0; n < o.max_devices; ++n) {
    std::optional<lss::Address> a;
    try {
      a = m.fastscan();
    } catch (const std::exception& e) {
      r.problems.push_back(std::string(e.what()) + ": run it again; if it keeps failing, connect the devices "
                                                   "without node-ID one at a time");
      break;
    }
    if (!a) break;
    const int id = free_id();
    const std::string who = "the device " + lss::to_string(*a);
    if (id > 127) {
      r.problems.push_back("no free node-ID left for " + who);
      m.switch_global(false);
      break;
    }
    try {
      m.configure_node_id(static_cast<uint8_t>(id));
      if (o.bitrate) m.configure_bit_timing(o.bitrate);
      m.store();
    } catch (const std::exception& e) {
      r.problems.push_back(who + ": " + e.what() + "; set its node-ID on the device itself (switches or its tool)");
      // Unconfigure it again so it leaves the fastscan.
      m.switch_global(false);
      break;
    }
    // Back to waiting: the device takes its node-ID and boots under it.
    m.switch_global(false);
    r.assigned.push_back({*a, id});
    ++next;
  }
  return r;
}

}  // namespace cnc::commission
