#include "fieldbus/can/transport.hpp"

#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/util/strings.hpp"
#include "core/util/time.hpp"
#include "fieldbus/can/socketcan.hpp"

namespace cnc::can {

int64_t Transport::now_ns() const noexcept { return monotonic_ns(); }

const char* to_string(SendStatus s) noexcept {
  switch (s) {
    case SendStatus::Ok: return "ok";
    case SendStatus::WouldBlock: return "transmit queue full";
    case SendStatus::BusOff: return "bus-off";
    case SendStatus::Down: return "interface down";
    case SendStatus::Invalid: return "invalid frame";
    case SendStatus::Error: return "send failed";
  }
  return "?";
}

namespace {
struct Kind {
  std::string name;
  TransportOpener open;
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

void register_transport_kind(const std::string& kind, TransportOpener opener) {
  std::lock_guard<std::mutex> lock(kinds_mutex());
  const std::string name = to_lower(kind);
  for (Kind& k : kinds()) {
    if (k.name == name) {
      k.open = opener;
      return;
    }
  }
  kinds().push_back({name, opener});
}

std::unique_ptr<Transport> open_transport(std::string_view spec) {
  const auto colon = spec.find(':');
  if (colon == std::string_view::npos) {
    throw std::runtime_error("CAN interface \"" + std::string(spec) + "\": expected <kind>:<name>, e.g. socketcan:can0");
  }
  const std::string kind = to_lower(trim(spec.substr(0, colon)));
  const auto parts = split(spec.substr(colon + 1), ',');
  if (parts.empty() || trim(parts[0]).empty()) throw std::runtime_error("CAN interface \"" + std::string(spec) + "\": no name");
  const std::string name(trim(parts[0]));
  if (kind == "socketcan") {
    SocketCanOptions o;
    for (std::size_t i = 1; i < parts.size(); ++i) {
      const auto opt = trim(parts[i]);
      if (opt == "fd") o.fd = true;
      else throw std::runtime_error("CAN interface \"" + std::string(spec) + "\": unknown option \"" + std::string(opt) + "\"");
    }
    return std::make_unique<SocketCanTransport>(name, o);
  }
  std::vector<std::string> options;
  for (std::size_t i = 1; i < parts.size(); ++i) options.emplace_back(trim(parts[i]));
  std::string known = "socketcan";
  TransportOpener opener = nullptr;
  {
    std::lock_guard<std::mutex> lock(kinds_mutex());
    for (const Kind& k : kinds()) {
      if (k.name == kind) opener = k.open;
      known += ", " + k.name;
    }
  }
  if (opener) return opener(spec, name, options);
  throw std::runtime_error("CAN interface \"" + std::string(spec) + "\": unknown kind \"" + kind + "\" (this controller has: " +
                           known + (kind == "virtual" ? "; the simulated bus comes with the simulators, sim/)" : ")"));
}

}  // namespace cnc::can
