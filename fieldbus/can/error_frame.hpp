// Controller and bus errors as frames. Every transport reports errors as
// Frame{flags = kError} laid out like Linux SocketCAN error frames
// (linux/can/error.h): error classes in `id`, details in data[0..7]. The
// virtual bus produces the same layout, so one decoder and one bus-state
// tracker serve both. Realtime-safe: no allocation.
#pragma once

#include <cstdint>

#include "fieldbus/can/frame.hpp"

namespace cnc::can {

// Error classes (Frame::id of an error frame), as in linux/can/error.h.
enum ErrorClass : uint32_t {
  kErrTxTimeout = 0x001,
  kErrLostArbitration = 0x002,
  kErrController = 0x004,  // data[1]: ControllerStatus bits
  kErrProtocol = 0x008,    // data[2]: type, data[3]: location
  kErrTransceiver = 0x010,
  kErrNoAck = 0x020,
  kErrBusOff = 0x040,
  kErrBusError = 0x080,
  kErrRestarted = 0x100,
  kErrCounters = 0x200,    // data[6]: TX error counter, data[7]: RX error counter
};

// data[1] of a controller-class error frame.
enum ControllerStatus : uint8_t {
  kCtrlRxOverflow = 0x01,
  kCtrlTxOverflow = 0x02,
  kCtrlRxWarning = 0x04,
  kCtrlTxWarning = 0x08,
  kCtrlRxPassive = 0x10,
  kCtrlTxPassive = 0x20,
  kCtrlActive = 0x40,
};

// data[2] of a protocol-class error frame (subset used here).
enum ProtocolError : uint8_t {
  kProtBit = 0x01,
  kProtForm = 0x02,
  kProtStuff = 0x04,
  kProtTx = 0x80,  // the error happened while this controller transmitted
};

// Fault confinement states (ISO 11898-1): error counters below 96 are
// active, from 96 warning, from 128 passive, TX counter above 255 bus-off.
enum class BusState : uint8_t { ErrorActive, ErrorWarning, ErrorPassive, BusOff };

const char* to_string(BusState s) noexcept;
BusState bus_state_from_counters(unsigned tx_errors, unsigned rx_errors) noexcept;

struct ErrorInfo {
  uint32_t classes = 0;
  uint8_t controller = 0;      // ControllerStatus bits
  uint8_t protocol = 0;        // ProtocolError bits
  uint8_t protocol_location = 0;
  bool has_counters = false;
  uint8_t tx_errors = 0;
  uint8_t rx_errors = 0;
};

ErrorInfo decode_error_frame(const Frame& f) noexcept;

// Builders used by transports that synthesise error reports.
Frame make_error_frame(uint32_t classes, uint8_t controller = 0, uint8_t protocol = 0, unsigned tx_errors = 0,
                       unsigned rx_errors = 0) noexcept;

// Short description, e.g. "bus-off", "controller: TX passive", into buf.
char* describe_error(const ErrorInfo& e, char* buf, std::size_t size) noexcept;

// Follows error frames to know the controller's state (bus-off,
// error-passive, ...). Starts error-active.
class BusStateTracker {
 public:
  // Returns true when the state changed.
  bool on_error_frame(const Frame& f) noexcept;
  BusState state() const noexcept { return state_; }
  void reset() noexcept { state_ = BusState::ErrorActive; }

 private:
  BusState state_ = BusState::ErrorActive;
};

}  // namespace cnc::can
