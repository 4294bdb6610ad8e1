#include "fieldbus/ethercat/link.hpp"

#include <stdexcept>

#include "core/util/kind_registry.hpp"

namespace cnc::ethercat {
namespace {
KindRegistry<LinkOpener>& kinds() {
  static KindRegistry<LinkOpener> k;
  return k;
}
}  // namespace

void register_link_kind(const std::string& kind, LinkOpener opener) { kinds().add(kind, opener); }

std::unique_ptr<Link> open_link(const std::string& spec) {
  if (spec.rfind("raw:", 0) == 0) return open_raw_link(spec.substr(4));
  const auto colon = spec.find(':');
  std::string known = "raw";
  if (colon != std::string::npos) {
    const LinkOpener opener = kinds().find(spec.substr(0, colon), known);
    if (opener) return opener(spec.substr(colon + 1));
  }
  throw std::runtime_error("EtherCAT interface \"" + spec + "\": expected raw:<interface> (this controller has: " + known +
                           (spec.rfind("sim:", 0) == 0 ? "; simulated segments come with the simulators, sim/)" : ")"));
}

}  // namespace cnc::ethercat
