// What a fieldbus gives the drive layer, independent of the transport
// (CANopen, EtherCAT CoE): per drive, where each cyclically
// mapped object lives in the process image, a realtime request/poll path
// for the few objects that are not mapped (mode, touch probe, error code),
// a blocking path for configuration at start-up, and the health of the
// link. Slots are read and written by the servo thread only, between the
// bus's read and write functions; never allocate, never block there.
// The drive layer owns this interface; each bus implements it in its own
// folder (fieldbus/canopen/cia402_binding, fieldbus/ethercat/cia402_binding)
// and registers a finder, so cia402/ never includes a bus.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "cia402/profile.hpp"
#include "core/util/process_slot.hpp"

namespace cnc::hal {
class Hal;
}

namespace cnc::cia402 {

// One mapped object in the bus's process image: the process-image slot of
// core/util/process_slot.hpp (read_slot / write_slot), handed through by
// every bus unchanged.
using Slot = ProcessSlot;

// Health of one drive's link, refreshed by the bus every cycle.
struct LinkHealth {
  bool operational = false;    // the device exchanges process data (CANopen Operational, EtherCAT OP)
  bool inputs_fresh = false;   // this cycle's inputs answered the last cycle (else they are stale)
  bool lost = false;           // heartbeat lost, device reset, or left the cyclic state
  uint16_t emcy_code = 0;      // last emergency code (0 after an error reset)
  uint32_t emcy_count = 0;
};

// Result of an acyclic realtime request.
struct AcyclicResult {
  uint32_t abort_code = 0;  // 0 = done
  uint32_t value = 0;       // reads
};

// Result of a blocking (non-realtime) transfer at start-up.
struct ConfigResult {
  bool ok = false;
  uint32_t abort_code = 0;
  uint64_t value = 0;  // reads, little-endian up to 8 bytes
  std::string text;    // "SDO download 0x6098:00 aborted by the server: 0x06090030 value range exceeded"
};

class DriveLink {
 public:
  virtual ~DriveLink() = default;

  // Name of the bus for messages ("canopen.0").
  virtual const std::string& name() const noexcept = 0;
  // What makes a drive "lost" on this bus, in its own words, for the
  // message when it happens ("heartbeat lost, reset, or no longer
  // operational" on CANopen).
  virtual const char* loss_causes() const noexcept { return "no longer in the cyclic exchange"; }
  // Drive "address" is the node-ID on CANopen, the ring position on EtherCAT.
  virtual bool has_device(int address) const noexcept = 0;

  // --- non-realtime (construction, start-up) ---
  // Where a mapped object lives: outputs are written by the master,
  // inputs read; an empty slot when the object is not mapped.
  virtual Slot output(int address, Object o) const noexcept = 0;
  virtual Slot input(int address, Object o) const noexcept = 0;
  // The order in which the frame that last carried an input slot arrived
  // (larger = later), for values that must come from the same or a later
  // frame than another (a touch probe's position after the status bit that
  // says it was latched, which may travel in another, rate-limited PDO).
  // 0: not known, or every input arrives in one frame (coherent). Servo thread.
  virtual uint64_t input_sequence(const Slot& s) const noexcept {
    (void)s;
    return 0;
  }
  // Blocking transfers for configuration (never from the servo thread).
  virtual ConfigResult read_wait(int address, Object o, unsigned size) = 0;
  virtual ConfigResult write_wait(int address, Object o, uint64_t value, unsigned size) = 0;
  // Cycle period of the bus, ns.
  virtual int64_t cycle_ns() const noexcept = 0;

  // --- realtime (servo thread) ---
  virtual LinkHealth health(int address) const noexcept = 0;
  // Expedited acyclic access (<= 4 bytes): a handle, or -1 when busy.
  virtual int request_read(int address, Object o) noexcept = 0;
  virtual int request_write(int address, Object o, uint32_t value, unsigned size) noexcept = 0;
  // True once, when the request has finished (result in `out`).
  virtual bool poll(int handle, AcyclicResult& out) noexcept = 0;
};

// The link of a bus by its HAL prefix ("canopen.0", "ethercat.0"), asked of
// every registered finder; throws std::runtime_error naming the bus when
// none knows it. Non-realtime (loadrt cia402).
std::unique_ptr<DriveLink> find_link(hal::Hal& hal, const std::string& bus);

// Each bus registers how to find its links by bus name (its
// register_components does); a finder returns null for a bus that is not
// its own. Registering the same finder twice keeps one.
using LinkFinder = std::unique_ptr<DriveLink> (*)(hal::Hal& hal, const std::string& bus);
void register_link_finder(LinkFinder finder);

}  // namespace cnc::cia402
