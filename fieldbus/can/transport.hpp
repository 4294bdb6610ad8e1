// A transport is one attachment to a CAN bus (one socket, one port of the
// virtual bus). A program that needs the bus from two threads opens two
// transports (the CANopen master: one for the servo thread, one for its
// acyclic thread), so no transport is ever shared between threads.
// send/receive never block and never allocate; wait() and set_filters() are
// for non-realtime threads.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "fieldbus/can/error_frame.hpp"
#include "fieldbus/can/frame.hpp"

namespace cnc::can {

enum class SendStatus : uint8_t {
  Ok,
  WouldBlock,  // transmit queue full: try again later (the frame was not queued)
  BusOff,      // the controller is bus-off: nothing can be sent until it recovers
  Down,        // interface down or closed
  Invalid,     // the frame is not valid for this transport (length, FD not enabled)
  Error,       // any other failure of the system call
};

const char* to_string(SendStatus s) noexcept;

// Acceptance filter with SocketCAN semantics: a frame passes when
// (frame id & mask) == (id & mask) and, if `match_extended`, its
// standard/extended kind equals `extended`.
struct Filter {
  uint32_t id = 0;
  uint32_t mask = 0;
  bool extended = false;
  bool match_extended = true;

  bool matches(const Frame& f) const noexcept {
    if (f.is_error()) return false;
    if (match_extended && f.is_extended() != extended) return false;
    return (f.id & mask) == (id & mask);
  }
  static Filter exact(uint32_t id) noexcept { return Filter{id, kStandardIdMask, false, true}; }
  static Filter range_mask(uint32_t id, uint32_t mask) noexcept { return Filter{id, mask, false, true}; }
};

struct TransportStats {
  uint64_t tx_frames = 0;
  uint64_t rx_frames = 0;
  uint64_t tx_rejected = 0;   // send() returned anything but Ok
  uint64_t rx_overruns = 0;   // frames lost because the receive queue was full
  uint64_t error_frames = 0;  // error reports received
};

class Transport {
 public:
  virtual ~Transport() = default;

  virtual const std::string& name() const noexcept = 0;
  virtual SendStatus send(const Frame& f) noexcept = 0;
  // Next received frame (data, remote or, when enabled, error report);
  // false when none is waiting.
  virtual bool receive(Frame& out) noexcept = 0;
  // Blocks until a frame may be waiting or `timeout_ns` passed. Non-realtime.
  virtual bool wait(int64_t timeout_ns) noexcept = 0;
  // Receive only frames matching one of the filters (an empty list = all).
  virtual void set_filters(std::span<const Filter> filters) = 0;
  // Deliver error reports as kError frames (on by default).
  virtual void set_error_reports(bool on) = 0;
  virtual BusState state() const noexcept = 0;
  virtual TransportStats stats() const noexcept = 0;
  // Bus bit rate when the transport knows it (the virtual bus does; a
  // SocketCAN interface reports it when the driver has bit timing), else 0.
  virtual uint32_t bitrate() const noexcept { return 0; }
  // The bus's clock, in which received frames are time-stamped and its
  // users' timeouts should run: CLOCK_MONOTONIC, or a virtual bus's own
  // (manual) clock, which stands still while nothing advances it.
  virtual int64_t now_ns() const noexcept;
};

// Opens a transport from a text specification "<kind>:<name>[,options]":
//   socketcan:<ifname>[,fd]          a SocketCAN raw socket (e.g. socketcan:can0)
//   unix:<path>                      a bus another process offers on a local
//                                    socket (unix_transport.hpp)
// and the kinds registered with register_transport_kind, e.g. the simulated
// in-process bus of sim/can (virtual:<bus>[,bitrate=N][,stuffing=...]).
// Throws std::runtime_error with the reason on failure. Non-realtime.
std::unique_ptr<Transport> open_transport(std::string_view spec);

// Opens a transport of a registered kind: `name` and `options` are the
// specification's parts after the colon, split at commas and trimmed;
// `spec` is the whole text for messages. Throws std::runtime_error.
using TransportOpener = std::unique_ptr<Transport> (*)(std::string_view spec, const std::string& name,
                                                       const std::vector<std::string>& options);
// Adds a kind of transport beyond SocketCAN (the simulators do, for
// "virtual"); `kind` is matched without regard to case. Registering a kind
// again replaces its opener. Non-realtime, before the transports are opened.
void register_transport_kind(const std::string& kind, TransportOpener opener);

}  // namespace cnc::can
