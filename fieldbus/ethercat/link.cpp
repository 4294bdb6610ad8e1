#include "fieldbus/ethercat/link.hpp"

#include <mutex>
#include <stdexcept>
#include <vector>

namespace cnc::ethercat {
namespace {
struct Kind {
  std::string name;
  LinkOpener open;
};
std::mutex& kinds_mutex() {
  static std::mutex m;
  return m;
}
std::vector<Kind>& kinds() {
  static std::vector<Kind> k;
  return k;
}
}  // namespace

void register_link_kind(const std::string& kind, LinkOpener opener) {
  std::lock_guard<std::mutex> lock(kinds_mutex());
  for (Kind& k : kinds()) {
    if (k.name == kind) {
      k.open = opener;
      return;
    }
  }
  kinds().push_back({kind, opener});
}

std::unique_ptr<Link> open_link(const std::string& spec) {
  if (spec.rfind("raw:", 0) == 0) return open_raw_link(spec.substr(4));
  const auto colon = spec.find(':');
  std::string known = "raw";
  if (colon != std::string::npos) {
    LinkOpener opener = nullptr;
    {
      std::lock_guard<std::mutex> lock(kinds_mutex());
      for (const Kind& k : kinds()) {
        if (k.name == spec.substr(0, colon)) opener = k.open;
        known += ", " + k.name;
      }
    }
    if (opener) return opener(spec.substr(colon + 1));
  }
  throw std::runtime_error("EtherCAT interface \"" + spec + "\": expected raw:<interface> (this controller has: " + known +
                           (spec.rfind("sim:", 0) == 0 ? "; simulated segments come with the simulators, sim/)" : ")"));
}

}  // namespace cnc::ethercat
