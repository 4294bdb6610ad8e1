#include "fieldbus/ethercat/link.hpp"

#include <stdexcept>

#include "fieldbus/ethercat/sim/segment.hpp"

namespace cnc::ethercat {

std::unique_ptr<Link> open_link(const std::string& spec) {
  if (spec.rfind("raw:", 0) == 0) return open_raw_link(spec.substr(4));
  if (spec.rfind("sim:", 0) == 0) {
    auto seg = sim::find_segment(spec.substr(4));
    if (!seg) {
      throw std::runtime_error("no simulated EtherCAT segment \"" + spec.substr(4) +
                               "\" (loadrt ethercat_sim name=" + spec.substr(4) + " before loadrt ethercat)");
    }
    return sim::open_sim_link(seg, spec.substr(4));
  }
  throw std::runtime_error("EtherCAT interface \"" + spec + "\": expected raw:<interface> or sim:<segment>");
}

}  // namespace cnc::ethercat
