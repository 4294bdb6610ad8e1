// The drive simulator as a HAL component, for simulated machines:
//   loadrt cia402_sim [sections=CIA402_SIM[,CIA402_SIM_1]]
// Each section's drives run on its INTERFACE (an in-process virtual bus, or
// a SocketCAN interface) in a thread of their own, started at load time so
// that the fieldbus master loaded next finds them booting. On a virtual bus
// (CLOCK = SERVO) that thread is the component's stepper: the servo
// thread's cia402-sim.<g>.update asks it for one period per cycle and never
// waits for it; the status shows the stepper's time apart. Pins per drive,
// cia402-sim.<g>.node.<id>.*: table-position (the true position, mm, as an
// interferometer reads it), following-error (increments), temperature,
// state, probe-in (an external probe signal, ORed with the node's own
// PROBE_POSITION input) and probe-level (that own input alone, e.g. the
// tool setter, for wiring to other drives' probe-in). Fault injection through
// the `sim-inject` command (`cnc inject "drive 1 overcurrent"`).
#pragma once

namespace cnc::hal {
class ComponentRegistry;
}

namespace cnc::cia402::sim {

void register_sim_component(hal::ComponentRegistry& registry);

}  // namespace cnc::cia402::sim
