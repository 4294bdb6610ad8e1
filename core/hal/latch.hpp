// The position latch: for a bit input and a float position, records in the
// servo cycle where each rising and falling edge of the input happened
// (halfway between the positions of the cycle before the edge and of the
// cycle that saw it), how many edges of each kind there were and in which
// direction the position moved. A non-realtime reader (the commissioning
// switch search through halcmd) reads the pins after a move, so it finds
// an edge to within a servo cycle of travel however slowly it polls. Its
// function runs in the servo thread: no allocation, no lock, no throw.
#pragma once

namespace cnc::hal {

class ComponentRegistry;

// `loadrt latch [count=N|names=a,b]`, one function per instance (named
// after it; add it last to the servo thread so it sees the cycle's values).
// Pins of each instance N:
//   N.in (bit, IN), N.position (float, IN);
//   N.input-lead-cycles (s32, IN, 0): 1 when `in` reaches the HAL a cycle
//     ahead of `position` (a CANopen drive's inputs in an event-driven
//     TPDO, its position in a synchronous one): the edge is then placed
//     between the position of the cycle that saw it and the next one's;
//   N.rise-position, N.fall-position (float, OUT): where the last rising /
//     falling edge of `in` happened;
//   N.rise-count, N.fall-count (s32, OUT): edges of each kind since loaded;
//   N.rise-direction, N.fall-direction (s32, OUT): the sign of the travel
//     across that edge (+1, -1, 0 standing);
//   N.last-edge (s32, OUT): +1 rising, -1 falling, 0 none yet;
//   N.arm (bit, IN, FALSE), N.changed (bit, OUT): while `arm` is FALSE,
//     `changed` is FALSE and the input's level is the reference; from the
//     first cycle `arm` is TRUE, `changed` turns TRUE in the cycle the
//     input differs from that reference and stays TRUE (through bounces)
//     until `arm` is FALSE again. Linked to motion.jog-stop it stops a jog
//     in the servo cycle a switch changes, whatever its polarity;
//   N.changed-position (float, OUT): where `changed` last turned TRUE,
//     placed as an edge is (bounces and chatter after it do not move it).
// The first cycle only takes the input's level (a TRUE input at start is
// not an edge); linking `in` to another pin at run time may count one edge.
void register_latch_component(ComponentRegistry& registry);

}  // namespace cnc::hal
