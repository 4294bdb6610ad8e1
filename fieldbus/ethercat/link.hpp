// The wire under the master: sends and receives whole EtherCAT frames.
// Implementations: a raw AF_PACKET socket on a named Ethernet interface
// ("raw:eth0"), and kinds registered by others: the simulators' in-process
// link to a simulated segment ("sim:<name>", sim/ethercat/segment.hpp). send() and receive() with timeout 0 never block: the
// servo thread uses them; receive() with a timeout is for other threads.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "fieldbus/ethercat/frame.hpp"

namespace cnc::ethercat {

class Link {
 public:
  virtual ~Link() = default;
  virtual const std::string& name() const noexcept = 0;
  virtual const Mac& mac() const noexcept = 0;
  // False when the frame could not be queued (interface down, buffer full).
  virtual bool send(const uint8_t* frame, std::size_t size) noexcept = 0;
  // One received EtherCAT frame into `buffer` (kMaxFrame bytes): its size,
  // or 0 when none arrived within `timeout_ns` (0: do not wait).
  virtual std::size_t receive(uint8_t* buffer, int64_t timeout_ns) noexcept = 0;
};

// "raw:<interface>" or "<kind>:<name>" of a registered kind; throws
// std::runtime_error with the reason (no such interface, not permitted, no
// such segment, unknown kind).
std::unique_ptr<Link> open_link(const std::string& spec);
// Adds a kind of link (the simulators do, for "sim"); the opener gets the
// name after the colon and throws std::runtime_error with the reason.
// Registering a kind again replaces its opener. Non-realtime.
using LinkOpener = std::unique_ptr<Link> (*)(const std::string& name);
void register_link_kind(const std::string& kind, LinkOpener opener);
std::unique_ptr<Link> open_raw_link(const std::string& interface);

}  // namespace cnc::ethercat
