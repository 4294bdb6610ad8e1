#include "fieldbus/can/transport.hpp"

#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/util/kind_registry.hpp"
#include "core/util/strings.hpp"
#include "core/util/time.hpp"
#include "fieldbus/can/socketcan.hpp"
#include "fieldbus/can/unix_transport.hpp"

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
KindRegistry<TransportOpener>& kinds() {
  static KindRegistry<TransportOpener> k;
  return k;
}
}  // namespace

void register_transport_kind(const std::string& kind, TransportOpener opener) {
  kinds().add(to_lower(kind), opener);
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
      else if (opt.rfind("bitrate=", 0) == 0) {
        const auto v = parse_uint(opt.substr(8));
        if (!v || *v == 0 || *v > 10'000'000) {
          throw std::runtime_error("CAN interface \"" + std::string(spec) + "\": bitrate \"" + std::string(opt.substr(8)) +
                                   "\" is not a bitrate in bit/s");
        }
        o.expected_bitrate = static_cast<uint32_t>(*v);
      } else throw std::runtime_error("CAN interface \"" + std::string(spec) + "\": unknown option \"" + std::string(opt) + "\"");
    }
    return std::make_unique<SocketCanTransport>(name, o);
  }
  if (kind == "unix") {
    if (parts.size() > 1) throw std::runtime_error("CAN interface \"" + std::string(spec) + "\": unix:<socket path> takes no options");
    return std::make_unique<UnixSocketTransport>(std::string(spec), name);
  }
  std::vector<std::string> options;
  for (std::size_t i = 1; i < parts.size(); ++i) options.emplace_back(trim(parts[i]));
  std::string known = "socketcan, unix";
  const TransportOpener opener = kinds().find(kind, known);
  if (opener) return opener(spec, name, options);
  throw std::runtime_error("CAN interface \"" + std::string(spec) + "\": unknown kind \"" + kind + "\" (this controller has: " +
                           known + (kind == "virtual" ? "; the simulated bus comes with the simulators, sim/)" : ")"));
}

}  // namespace cnc::can
