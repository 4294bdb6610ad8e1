// The registry of bus link finders (cia402/link.hpp).
#include <stdexcept>
#include <vector>

#include "cia402/link.hpp"

namespace cnc::cia402 {
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
  for (LinkFinder f : finders()) {
    if (auto link = f(hal, bus)) return link;
  }
  throw std::runtime_error("no fieldbus \"" + bus + "\" is loaded (loadrt canopen or ethercat before loadrt cia402)");
}

}  // namespace cnc::cia402
