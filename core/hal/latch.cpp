#include "core/hal/latch.hpp"

#include <cstdint>

#include "core/hal/component.hpp"
#include "core/hal/instances.hpp"

namespace cnc::hal {
namespace {

int32_t next(int32_t n) noexcept { return static_cast<int32_t>(static_cast<uint32_t>(n) + 1u); }  // wraps

struct PositionLatch {
  BitPin in;
  FloatPin position, rise_position, fall_position;
  S32Pin rise_count, fall_count, rise_direction, fall_direction, last_edge;
  bool primed = false, last_in = false;
  double last_position = 0;

  template <class C> void make(C& c, const std::string& n) {
    in = c.template pin<bool>(n + ".in", PinDir::In);
    position = c.template pin<double>(n + ".position", PinDir::In);
    rise_position = c.template pin<double>(n + ".rise-position", PinDir::Out);
    fall_position = c.template pin<double>(n + ".fall-position", PinDir::Out);
    rise_count = c.template pin<int32_t>(n + ".rise-count", PinDir::Out);
    fall_count = c.template pin<int32_t>(n + ".fall-count", PinDir::Out);
    rise_direction = c.template pin<int32_t>(n + ".rise-direction", PinDir::Out);
    fall_direction = c.template pin<int32_t>(n + ".fall-direction", PinDir::Out);
    last_edge = c.template pin<int32_t>(n + ".last-edge", PinDir::Out);
  }

  void update(const rt::CycleInfo&) noexcept {
    const bool v = in.get();
    const double p = position.get();
    if (primed && v != last_in) {
      // The input changed somewhere between the two samples: halfway.
      const double at = 0.5 * (p + last_position);
      const int32_t dir = p > last_position ? 1 : p < last_position ? -1 : 0;
      // Position before count: a reader that sees the new count sees its position.
      if (v) {
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
