#include "fieldbus/can/transport.hpp"

#include <stdexcept>

#include "core/util/strings.hpp"
#include "core/util/time.hpp"
#include "fieldbus/can/socketcan.hpp"
#include "fieldbus/can/virtual_bus.hpp"

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

std::unique_ptr<Transport> open_transport(std::string_view spec) {
  const auto colon = spec.find(':');
  if (colon == std::string_view::npos) {
    throw std::runtime_error("CAN interface \"" + std::string(spec) +
                             "\": expected socketcan:<interface> or virtual:<bus>[,bitrate=N][,stuffing=...]");
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
  if (kind == "virtual") {
    VirtualBusOptions o;
    o.manual_clock = false;
    for (std::size_t i = 1; i < parts.size(); ++i) {
      const auto opt = trim(parts[i]);
      const auto eq = opt.find('=');
      const auto key = opt.substr(0, eq);
      const auto value = eq == std::string_view::npos ? std::string_view{} : trim(opt.substr(eq + 1));
      if (key == "bitrate") {
        const auto n = parse_uint(value);
        if (!n || *n == 0 || *n > 1'000'000) throw std::runtime_error("CAN interface \"" + std::string(spec) + "\": bitrate must be 1..1000000");
        o.bitrate = static_cast<uint32_t>(*n);
      } else if (key == "stuffing") {
        if (value == "worst") o.stuffing = Stuffing::WorstCase;
        else if (value == "exact") o.stuffing = Stuffing::Exact;
        else if (value == "nominal") o.stuffing = Stuffing::Nominal;
        else throw std::runtime_error("CAN interface \"" + std::string(spec) + "\": stuffing must be worst, exact or nominal");
      } else {
        throw std::runtime_error("CAN interface \"" + std::string(spec) + "\": unknown option \"" + std::string(opt) + "\"");
      }
    }
    return VirtualBus::named(name, o)->open_port("port");
  }
  throw std::runtime_error("CAN interface \"" + std::string(spec) + "\": unknown kind \"" + kind + "\" (socketcan or virtual)");
}

}  // namespace cnc::can
