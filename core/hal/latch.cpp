#include "core/hal/latch.hpp"

#include <cstdint>

#include "core/hal/component.hpp"
#include "core/hal/instances.hpp"

namespace cnc::hal {
namespace {

int32_t next(int32_t n) noexcept { return static_cast<int32_t>(static_cast<uint32_t>(n) + 1u); }  // wraps

struct PositionLatch {
  BitPin in, arm, changed;
  FloatPin position, rise_position, fall_position, changed_position;
  S32Pin input_lead, rise_count, fall_count, rise_direction, fall_direction, last_edge;
  bool primed = false, last_in = false;
  bool pending = false, pending_rising = false;  // an edge waiting for the next cycle's position
  bool reference = false;                         // the input's level while disarmed
  bool pending_changed = false;                   // changed-position waiting for the next cycle's position
  double last_position = 0;

  template <class C> void make(C& c, const std::string& n) {
    in = c.template pin<bool>(n + ".in", PinDir::In);
    position = c.template pin<double>(n + ".position", PinDir::In);
    input_lead = c.template pin<int32_t>(n + ".input-lead-cycles", PinDir::In);
    rise_position = c.template pin<double>(n + ".rise-position", PinDir::Out);
    fall_position = c.template pin<double>(n + ".fall-position", PinDir::Out);
    rise_count = c.template pin<int32_t>(n + ".rise-count", PinDir::Out);
    fall_count = c.template pin<int32_t>(n + ".fall-count", PinDir::Out);
    rise_direction = c.template pin<int32_t>(n + ".rise-direction", PinDir::Out);
    fall_direction = c.template pin<int32_t>(n + ".fall-direction", PinDir::Out);
    last_edge = c.template pin<int32_t>(n + ".last-edge", PinDir::Out);
    arm = c.template pin<bool>(n + ".arm", PinDir::In);
    changed = c.template pin<bool>(n + ".changed", PinDir::Out);
    changed_position = c.template pin<double>(n + ".changed-position", PinDir::Out);
  }

  // The input changed somewhere between the position samples `before`
  // and `after`: halfway.
  void record(bool rising, double before, double after) noexcept {
    const double at = 0.5 * (before + after);
    const int32_t dir = after > before ? 1 : after < before ? -1 : 0;
    // Position before count: a reader that sees the new count sees its position.
    if (rising) {
      rise_position.set(at);
      rise_direction.set(dir);
      rise_count.set(next(rise_count.get()));
      last_edge.set(1);
    } else {
      fall_position.set(at);
      fall_direction.set(dir);
      fall_count.set(next(fall_count.get()));
      last_edge.set(-1);
    }
  }

  void update(const rt::CycleInfo&) noexcept {
    const bool v = in.get();
    const double p = position.get();
    if (pending) {
      record(pending_rising, last_position, p);
      pending = false;
    }
    if (pending_changed) {
      changed_position.set(0.5 * (last_position + p));
      pending_changed = false;
    }
    if (primed && v != last_in) {
      // An input that arrives a cycle ahead of the position (an
      // event-driven PDO beside a synchronous one) changed between this
      // cycle's position and the next one's.
      if (input_lead.get() > 0) {
        pending = true;
        pending_rising = v;
      } else {
        record(v, last_position, p);
      }
    }
    if (!arm.get()) {
      reference = v;
      changed.set(false);
    } else if (v != reference && !changed.get()) {
      changed.set(true);
      // Where, as an edge (a later bounce or chatter does not move it).
      if (input_lead.get() > 0) pending_changed = true;
      else changed_position.set(0.5 * (last_position + p));
    }
    last_in = v;
    last_position = p;
    primed = true;
  }
};

}  // namespace

void register_latch_component(ComponentRegistry& r) {
  add_instances<PositionLatch>(r, "latch", "latch",
                               "latch [count=N|names=a,b]: the position at each rising and falling edge of a bit, "
                               "latched in the servo cycle (rise-position, fall-position, counts)");
}

}  // namespace cnc::hal
