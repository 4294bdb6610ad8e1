// Offers an in-process virtual bus to other processes: "virtual:<bus>,share"
// (or share=<path>) makes the process that owns the bus (cncd with the
// simulated drives) listen on a Unix SOCK_SEQPACKET socket, by default
// /dev/shm/cnc-<instance>.can-<bus>; another process opens the same bus as
// "unix:<path>" (fieldbus/can/unix_transport.hpp), one more controller on
// it. That is how `cnc-commission scan` and `backup` reach the simulated
// drives inside a running cncd, as they reach real drives on socketcan:can0.
//
// A thread of its own (non-realtime) carries the frames: while a client is
// connected it holds one port on the bus, forwards the bus's frames to every
// client and each client's frames onto the bus and to the other clients
// (polling every millisecond; without clients it only waits for one and
// holds no port, so the bus is as it was). Simulation only (sim/).
#pragma once

#include <memory>
#include <string>

namespace cnc::can {

class VirtualBus;

// /dev/shm/cnc-<instance>.can-<bus>, the instance as the shared segment's
// (--instance of cncd, else $CNC_INSTANCE, else "default").
std::string default_share_path(const std::string& bus_name);

// Starts offering `bus` at `path` (once per path: later calls for the same
// path do nothing). When a live process already offers a bus there, the bus
// is not shared and a warning naming the path says so on standard error
// (the simulation runs on; only other processes cannot reach it). A socket
// file left by a process that ended is replaced. Throws std::runtime_error
// naming the path when the socket cannot be made. Non-realtime.
void share_virtual_bus(const std::shared_ptr<VirtualBus>& bus, const std::string& bus_name, const std::string& path);

}  // namespace cnc::can
