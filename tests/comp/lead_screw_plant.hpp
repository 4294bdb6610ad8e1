// A small lead-screw plant for the closed-loop test, standing in for a
// drive simulator's mechanics: the motor (encoder) position drives a nut
// through a screw with a pitch error (scale error, a local wave, the
// lead-periodic error), the table follows the nut with lost motion
// (backlash, varying along travel) and expands with temperature; a laser
// interferometer reads the table with noise.
//   loadrt lead_screw_plant [seed=N]
//   pins: lead-screw.motor-pos (in), lead-screw.table-pos (out, what the
//   interferometer reads), lead-screw.temperature (out)
// Test-only: registered by the tests, never by the controller.
#pragma once

#include "comp/synthetic.hpp"
#include "core/hal/component.hpp"

namespace cnc::testing {

// The plant's errors (the same terms as the fitted model, so that the test
// can say what the fit should find). The deviation is table minus motor.
comp::SyntheticAxis lead_screw_truth();

void register_lead_screw_plant(hal::ComponentRegistry& registry);

}  // namespace cnc::testing
