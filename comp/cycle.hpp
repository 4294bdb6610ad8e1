// The measurement cycles the controller runs to measure an axis, as G-code
// programs (machine coordinates, exact stop):
//  - the ISO 230-2 standard test cycle: targets spaced unevenly on purpose
//    (P_i = (i - 1) p + r_i, r_i random and seeded, so that periodic errors
//    are not sampled in phase), each approached `runs` times in each
//    direction in a linear cycle, with an overshoot past the end targets
//    before each reversal and a dwell at each target for the measurement;
//  - dense short runs over a few screw leads at several places (ISO 230-2
//    Annex C), which the periodic error needs.
// Two digital outputs of motion mark the measurement for the logger, each
// set with M62 (synchronised with the next move): P<n> (complog.enable)
// when the move to the first target starts, P<n+1> (complog.stop) when the
// move after the last target starts; both are cleared at the program's
// start with M65. (Two outputs rather than M62/M63 on one: the program is
// read ahead, and a later M63 on the same output would replace the M62
// still waiting for its move.) Offline.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace cnc::comp {

struct CycleOptions {
  char axis = 'X';
  double x_min = 0, x_max = 0;   // first and last target (machine coordinates)
  int targets = 0;               // 0: at least 5, and at least 5 per metre, about one per 25 mm
  int runs = 5;                  // each direction
  double overshoot_mm = 2;       // past the end targets before reversing
  double dwell_s = 0.8;          // at each target (the logger settles, then averages)
  double feed_mm_min = 3000;
  uint64_t seed = 1;             // for the targets' random offsets
  int digital_out = 0;           // motion.digital-out-NN: complog.enable; NN + 1: complog.stop
  // Dense periodic runs (Annex C)
  double lead_mm = 5;
  int periodic_places = 3;       // spread over the travel
  double periodic_leads = 2;     // length of each run in leads
  int periodic_steps_per_lead = 8;
  int periodic_runs = 2;         // each direction
};

std::vector<double> iso_targets(const CycleOptions& o);
std::vector<double> periodic_targets(const CycleOptions& o, int place);
std::string iso_cycle_gcode(const CycleOptions& o);
std::string periodic_cycle_gcode(const CycleOptions& o);

}  // namespace cnc::comp
