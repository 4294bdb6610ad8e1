#include "fieldbus/can/error_frame.hpp"

#include <cstdio>

namespace cnc::can {

const char* to_string(BusState s) noexcept {
  switch (s) {
    case BusState::ErrorActive: return "error-active";
    case BusState::ErrorWarning: return "error-warning";
    case BusState::ErrorPassive: return "error-passive";
    case BusState::BusOff: return "bus-off";
  }
  return "?";
}

BusState bus_state_from_counters(unsigned tx_errors, unsigned rx_errors) noexcept {
  if (tx_errors > 255) return BusState::BusOff;
  if (tx_errors >= 128 || rx_errors >= 128) return BusState::ErrorPassive;
  if (tx_errors >= 96 || rx_errors >= 96) return BusState::ErrorWarning;
  return BusState::ErrorActive;
}

ErrorInfo decode_error_frame(const Frame& f) noexcept {
  ErrorInfo e;
  if (!f.is_error()) return e;
  e.classes = f.id;
  e.controller = f.data[1];
  e.protocol = f.data[2];
  e.protocol_location = f.data[3];
  e.has_counters = (f.id & kErrCounters) != 0;
  e.tx_errors = f.data[6];
  e.rx_errors = f.data[7];
  return e;
}

Frame make_error_frame(uint32_t classes, uint8_t controller, uint8_t protocol, unsigned tx_errors,
                       unsigned rx_errors) noexcept {
  Frame f;
  f.flags = kError;
  f.id = classes;
  f.len = 8;
  f.data[1] = controller;
  f.data[2] = protocol;
  if (classes & kErrCounters) {
    f.data[6] = static_cast<uint8_t>(tx_errors > 255 ? 255 : tx_errors);
    f.data[7] = static_cast<uint8_t>(rx_errors > 255 ? 255 : rx_errors);
  }
  return f;
}

char* describe_error(const ErrorInfo& e, char* buf, std::size_t size) noexcept {
  if (size == 0) return buf;
  buf[0] = '\0';
  std::size_t n = 0;
  auto add = [&](const char* text) {
    if (n >= size) return;
    const int w = std::snprintf(buf + n, size - n, "%s%s", n ? ", " : "", text);
    if (w > 0) n += static_cast<std::size_t>(w);
  };
  if (e.classes & kErrBusOff) add("bus-off");
  if (e.classes & kErrRestarted) add("controller restarted");
  if (e.classes & kErrController) {
    if (e.controller & kCtrlTxPassive) add("TX error-passive");
    if (e.controller & kCtrlRxPassive) add("RX error-passive");
    if (e.controller & kCtrlTxWarning) add("TX error-warning");
    if (e.controller & kCtrlRxWarning) add("RX error-warning");
    if (e.controller & kCtrlActive) add("back to error-active");
    if (e.controller & kCtrlRxOverflow) add("RX buffer overflow");
    if (e.controller & kCtrlTxOverflow) add("TX buffer overflow");
  }
  if (e.classes & kErrProtocol) {
    if (e.protocol & kProtBit) add("bit error");
    if (e.protocol & kProtForm) add("form error");
    if (e.protocol & kProtStuff) add("stuff error");
    if (!(e.protocol & (kProtBit | kProtForm | kProtStuff))) add("protocol violation");
  }
  if (e.classes & kErrNoAck) add("no acknowledge");
  if (e.classes & kErrTxTimeout) add("TX timeout");
  if (e.classes & kErrLostArbitration) add("lost arbitration");
  if (e.classes & kErrTransceiver) add("transceiver");
  if (e.classes & kErrBusError) add("bus error");
  if (n == 0) add("error frame");
  return buf;
}

bool BusStateTracker::on_error_frame(const Frame& f) noexcept {
  if (!f.is_error()) return false;
  const ErrorInfo e = decode_error_frame(f);
  BusState next = state_;
  if (e.classes & kErrBusOff) {
    next = BusState::BusOff;
  } else if (e.classes & kErrRestarted) {
    next = BusState::ErrorActive;
  } else if (e.classes & kErrController) {
    if (e.controller & (kCtrlTxPassive | kCtrlRxPassive)) next = BusState::ErrorPassive;
    else if (e.controller & (kCtrlTxWarning | kCtrlRxWarning)) next = BusState::ErrorWarning;
    else if (e.controller & kCtrlActive) next = BusState::ErrorActive;
  } else if (e.has_counters && state_ != BusState::BusOff) {
    next = bus_state_from_counters(e.tx_errors, e.rx_errors);
  }
  const bool changed = next != state_;
  state_ = next;
  return changed;
}

}  // namespace cnc::can
