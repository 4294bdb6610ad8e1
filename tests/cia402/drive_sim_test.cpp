// The drive simulator on its own (no bus): its state machine from the
// drive's side, statuswords, modes, homing methods against the plant's
// switches and index, touch probes, limits, following error, reactions to
// faults and to a lost connection, fault injection, and the plant.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "sim/cia402/drive_model.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using namespace cnc::cia402;
using namespace cnc::cia402::sim;

namespace {

constexpr double kCountsPerMm = 2000;  // 10000 increments per rev, 5 mm screw

DriveSimConfig base_config() {
  DriveSimConfig c;
  c.plant.encoder_counts = 10000;
  c.plant.lead_m = 0.005;
  c.plant.neg_limit = -0.040;
  c.plant.pos_limit = 0.040;
  c.plant.home_min = 0.010;
  c.plant.index_offset = 0.0013;
  return c;
}

struct SimDrive {
  explicit SimDrive(const DriveSimConfig& c = base_config()) : model(c, od) {
    model.on_emcy = [this](uint16_t code, uint8_t) { emcy.push_back(code); };
    model.power_on(0);
  }
  void cw(uint16_t v) { od.set<uint16_t>({0x6040, 0}, v); }
  void target(int64_t counts) { od.set<int32_t>({0x607A, 0}, static_cast<int32_t>(counts)); }
  void mode(Mode m) { od.set<int8_t>({0x6060, 0}, static_cast<int8_t>(m)); }
  // One SYNC: the statusword is sampled (as a TPDO is), what was written
  // takes effect, the drive runs one period (1 ms unless 0x60C2 says else).
  void sync() {
    t += period_ns;
    trace.push_back(model.statusword());
    model.on_sync(t);
  }
  void syncs(int n) {
    for (int i = 0; i < n; ++i) sync();
  }
  bool sync_until(const std::function<bool()>& pred, int max) {
    for (int i = 0; i < max; ++i) {
      sync();
      if (pred()) return true;
    }
    return false;
  }
  uint32_t sdo_write(uint16_t index, uint8_t sub, uint64_t value, std::size_t n) {
    uint8_t b[8];
    for (std::size_t i = 0; i < n; ++i) b[i] = static_cast<uint8_t>(value >> (8 * i));
    return od.write({index, sub}, b, n, true);
  }
  int64_t position() const { return od.get<int32_t>({0x6064, 0}); }
  double table_mm() const { return model.plant().table_position() * 1000.0; }
  State state() const { return model.state(); }
  void enable(Mode m = Mode::CyclicSyncPosition) {
    mode(m);
    syncs(25);  // power-on initialisation ends (T1)
    target(position());
    cw(0x06);
    sync();
    cw(0x07);
    sync();
    cw(0x0F);
    sync();
    ASSERT_EQ(state(), State::OperationEnabled);
  }
  // CSP ramp to `to_mm` at `mm_per_s`, then hold for `hold_ms`.
  void move_to(double to_mm, double mm_per_s, int hold_ms = 50) {
    double p = position() / kCountsPerMm;
    const double step = mm_per_s * 0.001;
    while (std::fabs(to_mm - p) > 1e-9) {
      p = std::fabs(to_mm - p) <= step ? to_mm : p + (to_mm > p ? step : -step);
      target(std::llround(p * kCountsPerMm));
      sync();
    }
    syncs(hold_ms);
  }

  canopen::ObjectDictionary od;
  DriveModel model;
  int64_t t = 0;
  int64_t period_ns = 1'000'000;
  std::vector<uint16_t> trace;
  std::vector<uint16_t> emcy;
};

}  // namespace

TEST(Cia402Sim, PowersUpNotReadyThenSwitchOnDisabled) {
  SimDrive d;
  EXPECT_EQ(d.state(), State::NotReadyToSwitchOn);
  EXPECT_EQ(d.model.statusword() & 0x4F, 0x00);
  d.syncs(25);
  EXPECT_EQ(d.state(), State::SwitchOnDisabled);  // T1
  EXPECT_EQ(d.model.statusword(), 0x0250);
}

TEST(Cia402Sim, EveryControlwordTransitionFromTheDriveSide) {
  SimDrive d;
  d.syncs(25);
  auto go = [&](uint16_t c) {
    d.cw(c);
    d.sync();
    return d.state();
  };
  EXPECT_EQ(go(0x06), State::ReadyToSwitchOn);   // T2
  EXPECT_EQ(d.model.statusword(), 0x0231);
  EXPECT_EQ(go(0x07), State::SwitchedOn);        // T3
  EXPECT_EQ(d.model.statusword(), 0x0233);
  EXPECT_EQ(go(0x0F), State::OperationEnabled);  // T4
  EXPECT_EQ(d.model.statusword() & 0x006F, 0x0027);
  EXPECT_EQ(go(0x07), State::SwitchedOn);        // T5 (0x605C = 1: ramp, at rest at once)
  EXPECT_EQ(go(0x06), State::ReadyToSwitchOn);   // T6
  EXPECT_EQ(go(0x00), State::SwitchOnDisabled);  // T7 (disable voltage)
  go(0x06);
  EXPECT_EQ(go(0x02), State::SwitchOnDisabled);  // T7 (quick stop)
  go(0x06);
  go(0x07);
  EXPECT_EQ(go(0x00), State::SwitchOnDisabled);  // T10 (disable voltage)
  go(0x06);
  go(0x07);
  EXPECT_EQ(go(0x02), State::SwitchOnDisabled);  // T10 (quick stop)
  go(0x06);
  EXPECT_EQ(go(0x0F), State::OperationEnabled);  // T3 + T4 in one step
  d.syncs(2);
  EXPECT_EQ(go(0x06), State::ReadyToSwitchOn);   // T8
  go(0x0F);
  EXPECT_EQ(go(0x00), State::SwitchOnDisabled);  // T9
  go(0x06);
  go(0x0F);
  d.cw(0x02);
  d.sync();
  EXPECT_TRUE(d.state() == State::QuickStopActive || d.state() == State::SwitchOnDisabled);  // T11
  EXPECT_TRUE(d.sync_until([&] { return d.state() == State::SwitchOnDisabled; }, 100));   // T12 after the ramp (0x605A = 2)
  // Commands that are not transitions of the current state change nothing.
  EXPECT_EQ(go(0x07), State::SwitchOnDisabled);
  EXPECT_EQ(go(0x0F), State::SwitchOnDisabled);
}

TEST(Cia402Sim, QuickStopOptionSixStaysInQuickStopUntilEnabledAgain) {
  SimDrive d;
  ASSERT_EQ(d.sdo_write(0x605A, 0, 6, 2), 0u);
  d.enable();
  d.cw(0x02);
  d.syncs(50);
  EXPECT_EQ(d.state(), State::QuickStopActive);  // T11, and it stays (option 5-8)
  EXPECT_EQ(d.model.statusword() & 0x006F, 0x0007);
  d.cw(0x0F);
  d.sync();
  EXPECT_EQ(d.state(), State::OperationEnabled);  // T16
  d.cw(0x02);
  d.syncs(20);
  d.cw(0x00);
  d.sync();
  EXPECT_EQ(d.state(), State::SwitchOnDisabled);  // T12 by disable voltage
}

TEST(Cia402Sim, QuickStopRampsOnTheQuickStopDeceleration) {
  SimDrive d;
  ASSERT_EQ(d.sdo_write(0x6085, 0, 100'000, 4), 0u);  // 50 mm/s^2
  d.enable();
  d.move_to(10, 20, 0);  // moving at 20 mm/s when the ramp starts
  const double from = d.table_mm();
  d.cw(0x02);
  int ms = 0;
  while (d.state() != State::SwitchOnDisabled && ms < 2000) {
    d.sync();
    ++ms;
  }
  EXPECT_EQ(d.state(), State::SwitchOnDisabled);
  // v^2 / 2a = 400 / 100 = 4 mm in 400 ms.
  EXPECT_NEAR(d.table_mm() - from, 4.0, 0.2);
  EXPECT_NEAR(ms, 400, 30);
  EXPECT_NEAR(d.model.plant().motor_velocity(), 0.0, 0.1);  // settled before the power went off
  d.syncs(20);
  EXPECT_EQ(d.model.plant().motor_velocity(), 0.0);
}

TEST(Cia402Sim, FaultResetActsOnTheRisingEdgeOnly) {
  SimDrive d;
  d.enable();
  d.model.inject_overcurrent();
  d.sync();
  EXPECT_EQ(d.state(), State::Fault);
  EXPECT_EQ(d.model.statusword(), 0x0218);
  EXPECT_EQ(d.od.get<uint16_t>({0x603F, 0}), 0x2310);
  ASSERT_EQ(d.emcy.size(), 1u);
  EXPECT_EQ(d.emcy[0], 0x2310);
  d.cw(0x80);
  d.sync();
  EXPECT_EQ(d.state(), State::SwitchOnDisabled);  // T15
  EXPECT_EQ(d.od.get<uint16_t>({0x603F, 0}), 0);
  EXPECT_EQ(d.emcy.back(), 0);  // EMCY error reset
  // A second fault while bit 7 stays high: no edge, no reset.
  d.cw(0x86);
  d.sync();
  d.model.inject_overcurrent();
  d.syncs(3);
  EXPECT_EQ(d.state(), State::Fault);
  d.syncs(10);
  EXPECT_EQ(d.state(), State::Fault);
  d.cw(0x00);
  d.sync();
  d.cw(0x80);
  d.sync();
  EXPECT_EQ(d.state(), State::SwitchOnDisabled);
}

TEST(Cia402Sim, FaultResetIsRefusedWhileTheCausePersists) {
  SimDrive d;
  d.enable();
  d.model.set_temperature_offset(70);  // 35 + 70 C > 90 C trip
  d.sync();
  EXPECT_TRUE(d.sync_until([&] { return d.state() == State::Fault; }, 500));
  EXPECT_EQ(d.model.error_code(), err::kOverTemperature);
  d.cw(0x00);
  d.sync();
  d.cw(0x80);
  d.sync();
  EXPECT_EQ(d.state(), State::Fault);
  d.model.set_temperature_offset(0);
  d.cw(0x00);
  d.sync();
  d.cw(0x80);
  d.sync();
  EXPECT_EQ(d.state(), State::SwitchOnDisabled);
}

TEST(Cia402Sim, OvertemperatureWarnsBeforeItTrips) {
  SimDrive d;
  d.enable();
  d.model.set_temperature_offset(50);  // 85 C: above the warning, below the trip
  d.syncs(5);
  EXPECT_EQ(d.state(), State::OperationEnabled);
  EXPECT_TRUE(d.model.statusword() & sw::kWarning);
  EXPECT_EQ(d.od.get<int16_t>({0x2000, 0}), 850);
}

TEST(Cia402Sim, FaultReactionRampsDownThenFaults) {
  SimDrive d;
  d.enable();
  ASSERT_EQ(d.sdo_write(0x6085, 0, 200'000, 4), 0u);  // 100 mm/s^2
  double p = 0;
  auto cruise = [&] {  // the master keeps sending set-points at 20 mm/s
    p += 0.02;
    d.target(std::llround(p * kCountsPerMm));
    d.sync();
  };
  for (int i = 0; i < 200; ++i) cruise();
  d.model.connection_lost(err::kHeartbeat);  // 0x6007 = 1: fault, reaction per 0x605E = 2 (quick-stop ramp)
  d.trace.clear();
  int ms = 0;
  for (; ms < 1000 && d.state() != State::Fault; ++ms) cruise();
  // The states the master saw, sample by sample (each sampled at a SYNC).
  std::vector<State> seen;
  for (uint16_t s : d.trace) {
    if (seen.empty() || seen.back() != decode_state(s)) seen.push_back(decode_state(s));
  }
  seen.push_back(d.state());
  ASSERT_EQ(seen.size(), 3u);
  EXPECT_EQ(seen[0], State::OperationEnabled);      // a warning first
  EXPECT_TRUE(d.trace[0] & sw::kWarning);
  EXPECT_EQ(seen[1], State::FaultReactionActive);   // T13: the ramp
  EXPECT_EQ(seen[2], State::Fault);                 // T14
  EXPECT_NEAR(ms, 200, 30);                         // 20 mm/s at 100 mm/s^2
  EXPECT_EQ(d.model.error_code(), err::kHeartbeat);
  d.syncs(20);
  EXPECT_EQ(d.model.plant().motor_velocity(), 0.0);
}

TEST(Cia402Sim, LostMasterReproducesThePublishedStatuswordTrace) {
  // A real servo losing its master: 0x1237 (OE) -> 0x12B7 (OE + warning)
  // -> 0x0218 (fault). At rest the fault reaction ends at once.
  SimDrive d;
  d.enable();
  d.syncs(5);
  EXPECT_EQ(d.model.statusword() & ~sw::kTargetReached, 0x1237);
  d.model.connection_lost(err::kHeartbeat);
  d.trace.clear();
  d.syncs(20);
  ASSERT_FALSE(d.trace.empty());
  EXPECT_EQ(d.trace.front() & ~sw::kTargetReached, 0x12B7);
  EXPECT_EQ(d.trace.back(), 0x0218);
}

TEST(Cia402Sim, AbortConnectionOptionsChooseTheReaction) {
  for (int option : {0, 2, 3}) {
    SimDrive d;
    ASSERT_EQ(d.sdo_write(0x6007, 0, static_cast<uint64_t>(option), 2), 0u);
    d.enable();
    d.model.connection_lost(err::kRpdoTimeout);
    d.syncs(200);
    const State want = option == 0 ? State::OperationEnabled : State::SwitchOnDisabled;
    EXPECT_EQ(d.state(), want) << "0x6007 = " << option;
    EXPECT_TRUE(d.emcy.empty());
  }
}

TEST(Cia402Sim, MissingSyncsAreALostConnection) {
  DriveSimConfig c = base_config();
  c.sync_timeout_ns = 30'000'000;
  SimDrive d(c);
  d.enable();
  // No more SYNCs: the drive keeps time by itself.
  for (int i = 1; i <= 100; ++i) d.model.advance_to(d.t + i * 1'000'000);
  EXPECT_EQ(d.state(), State::Fault);
  EXPECT_EQ(d.model.error_code(), err::kSyncLost);
}

TEST(Cia402Sim, EnablingStartsTheDemandWhereTheMotorIs) {
  SimDrive d;
  d.syncs(25);
  // A load pushed the table by hand while the drive was off (simulated by
  // an old target far away): enabling must not pull the table back to it.
  d.model.plant().set_extra_friction(0);
  d.target(50'000);
  d.cw(0x06);
  d.sync();
  d.cw(0x07);
  d.sync();
  d.target(d.position());  // what the master does before 0x000F
  d.cw(0x0F);
  const double before = d.table_mm();
  d.syncs(50);
  EXPECT_EQ(d.state(), State::OperationEnabled);
  EXPECT_NEAR(d.table_mm(), before, 0.001);
  EXPECT_NEAR(d.model.demand(), static_cast<double>(d.position()), 2.0);
}

TEST(Cia402Sim, FollowsCspTargetsWithinAFewIncrements) {
  SimDrive d;
  d.enable();
  double worst = 0;
  double p = 0;
  for (int i = 0; i < 1000; ++i) {  // 20 mm/s for one second
    p += 0.02;
    d.target(std::llround(p * kCountsPerMm));
    d.sync();
    if (i > 100) worst = std::max(worst, std::fabs(d.model.following_error()));
  }
  EXPECT_LT(worst, 20.0);  // 10 um at 20 mm/s with velocity and torque feed-forward
  EXPECT_TRUE(d.model.statusword() & sw::kBit12);
}

TEST(Cia402Sim, ModesSwitchOnlyToSupportedOnesAndTheDisplayMirrors) {
  SimDrive d;
  d.syncs(25);
  EXPECT_EQ(d.sdo_write(0x6060, 0, 1, 1), 0x06090030u);  // PP: not in 0x6502
  EXPECT_EQ(d.sdo_write(0x6060, 0, 9, 1), 0u);
  d.sync();
  EXPECT_EQ(d.od.get<int8_t>({0x6061, 0}), 9);
  EXPECT_EQ(d.model.mode(), Mode::CyclicSyncVelocity);
  EXPECT_EQ(d.od.get<uint32_t>({0x6502, 0}), (1u << 5) | (1u << 7) | (1u << 8) | (1u << 9));
}

TEST(Cia402Sim, CsvFollowsTheTargetVelocity) {
  SimDrive d;
  d.enable(Mode::CyclicSyncVelocity);
  d.od.set<int32_t>({0x60FF, 0}, 20'000);  // 10 mm/s
  d.syncs(500);
  EXPECT_NEAR(d.od.get<int32_t>({0x606C, 0}), 20'000, 1100);  // one increment per ms of averaging
  EXPECT_NEAR(d.model.plant().table_velocity() * 1000.0, 10.0, 0.2);
}

// 0x60F9 / 0x60FB: the loops' gains as objects (ServoGains: units).
TEST(Cia402Sim, LoopGainsAreObjectsWithTheConfiguredDefaults) {
  SimDrive d;
  const double j = d.model.plant().reflected_inertia();
  const double kv = j * 2 * M_PI * base_config().gains.velocity_bandwidth_hz;
  EXPECT_EQ(d.od.get<uint8_t>({0x60F9, 0}), 2);
  EXPECT_NEAR(d.od.get<uint32_t>({0x60F9, 1}), kv / 1e-4, 1.0);
  EXPECT_EQ(d.od.get<uint16_t>({0x60F9, 2}), std::lround(base_config().gains.velocity_integral_time / 1e-4));
  EXPECT_EQ(d.od.get<uint8_t>({0x60FB, 0}), 5);
  EXPECT_EQ(d.od.get<uint32_t>({0x60FB, 1}), std::lround(base_config().gains.position_gain * 100));
  EXPECT_EQ(d.od.get<uint16_t>({0x60FB, 4}), 1000);
  EXPECT_EQ(d.sdo_write(0x60F9, 1, 0, 4), 0x06090030u);    // no gain: refused
  EXPECT_EQ(d.sdo_write(0x60FB, 4, 1001, 2), 0x06090030u); // above 100 %
  EXPECT_NE(d.sdo_write(0x60FB, 2, 5, 2), 0u);             // the position loop has no integral
}

// The time the velocity takes to reach 90 % of a CSV step, for a
// velocity gain written by SDO (0.1 mN m s/rad).
static int csv_rise_ms(uint32_t velocity_gain) {
  SimDrive d;
  EXPECT_EQ(d.sdo_write(0x60F9, 1, velocity_gain, 4), 0u);
  d.enable(Mode::CyclicSyncVelocity);
  d.syncs(50);
  d.od.set<int32_t>({0x60FF, 0}, 20'000);  // 10 mm/s
  for (int ms = 1; ms <= 500; ++ms) {
    d.sync();
    if (d.model.plant().table_velocity() * 1000.0 >= 9.0) return ms;
  }
  return 1000;
}

TEST(Cia402Sim, AHigherVelocityGainWrittenTo60F9RisesFaster) {
  const uint32_t kv = SimDrive().od.get<uint32_t>({0x60F9, 1});
  const int slow = csv_rise_ms(kv / 10), fast = csv_rise_ms(kv / 5);
  EXPECT_LT(fast * 1.4, slow) << "rise " << fast << " ms at 20 %, " << slow << " ms at 10 % of the default gain";
}

TEST(Cia402Sim, CstAppliesTheTargetTorque) {
  SimDrive d;
  d.enable(Mode::CyclicSyncTorque);
  d.od.set<int16_t>({0x6071, 0}, 100);  // 10 % of rated
  d.syncs(5);
  EXPECT_NEAR(d.model.plant().torque(), 0.1 * base_config().plant.rated_torque, 0.01);
  EXPECT_NEAR(d.od.get<int16_t>({0x6077, 0}), 100, 2);
  EXPECT_GT(d.model.plant().motor_velocity(), 0.0);
}

// ---------------------------------------------------------------- homing

struct HomingCase {
  int method;
  double start_mm;
  bool negative_switch;  // home switch active below -10 mm instead of above +10 mm
  double reference_mm;   // where the reference lies on the nut
};

class Cia402SimHoming : public ::testing::TestWithParam<HomingCase> {};

TEST_P(Cia402SimHoming, FindsItsReferenceOnThePlant) {
  const HomingCase& hc = GetParam();
  DriveSimConfig c = base_config();
  c.plant.start_position = hc.start_mm / 1000.0;
  if (hc.negative_switch) {
    c.plant.home_min = -1.0;
    c.plant.home_max = -0.010;
  }
  SimDrive d(c);
  ASSERT_EQ(d.sdo_write(0x6098, 0, static_cast<uint8_t>(hc.method), 1), 0u);
  ASSERT_EQ(d.sdo_write(0x6099, 1, 40'000, 4), 0u);   // 20 mm/s to find the switch
  ASSERT_EQ(d.sdo_write(0x6099, 2, 4'000, 4), 0u);    // 2 mm/s through edges and to the index
  ASSERT_EQ(d.sdo_write(0x609A, 0, 400'000, 4), 0u);  // 200 mm/s^2
  ASSERT_EQ(d.sdo_write(0x607C, 0, 123'456, 4), 0u);  // the reference reads this afterwards
  d.enable(Mode::Homing);
  EXPECT_EQ(decode_homing(d.model.statusword()), HomingStatus::Interrupted);  // not started
  d.cw(0x1F);
  d.sync();
  if (hc.method != 35 && hc.method != 37) {
    EXPECT_EQ(decode_homing(d.model.statusword()), HomingStatus::InProgress);
  }
  ASSERT_TRUE(d.sync_until([&] { return decode_homing(d.model.statusword()) == HomingStatus::Completed; }, 30'000))
      << "method " << hc.method << ": " << to_string(decode_homing(d.model.statusword()));
  EXPECT_TRUE(d.model.homed());
  // The encoder count at the reference is where the position reads 0x607C.
  const double encoder_at_reference = static_cast<double>(d.model.plant().encoder() - (d.position() - 123'456));
  const double reference_mm = hc.start_mm + encoder_at_reference / kCountsPerMm;
  const bool edge = hc.method >= 17 && hc.method <= 30;
  EXPECT_NEAR(reference_mm, hc.reference_mm, edge ? 0.002 : 0.0006) << "method " << hc.method;
}

INSTANTIATE_TEST_SUITE_P(
    Methods, Cia402SimHoming,
    ::testing::Values(HomingCase{1, 0, false, -38.7},   // negative limit, then index
                      HomingCase{2, 0, false, 36.3},    // positive limit, then index
                      HomingCase{3, 0, false, 6.3},     // home switch (+ side), index left of its edge
                      HomingCase{3, 20, false, 6.3},    // ... starting on the switch
                      HomingCase{4, 0, false, 11.3},    // ... index right of its edge
                      HomingCase{4, 20, false, 11.3},
                      HomingCase{5, 0, true, -8.7},     // home switch (- side), index right of its edge
                      HomingCase{6, 0, true, -13.7},    // ... index left of its edge
                      HomingCase{17, 0, false, -40.0},  // negative limit switch edge
                      HomingCase{18, 0, false, 40.0},   // positive limit switch edge
                      HomingCase{19, 0, false, 10.0},   // home switch edges
                      HomingCase{20, 0, false, 10.0},
                      HomingCase{21, 0, true, -10.0},
                      HomingCase{22, 0, true, -10.0},
                      HomingCase{33, 0, false, -3.7},   // index, negative direction
                      HomingCase{34, 0, false, 1.3},    // index, positive direction
                      HomingCase{35, 0, false, 0.0},    // here
                      HomingCase{37, 0, false, 0.0}),
    [](const ::testing::TestParamInfo<HomingCase>& i) {
      return "Method" + std::to_string(i.param.method) + "From" + std::to_string(static_cast<int>(i.param.start_mm));
    });

TEST(Cia402Sim, HomingStopsWithAnErrorAtAnUnexpectedLimit) {
  DriveSimConfig c = base_config();
  c.plant.home_min = 1.0;  // no home switch within the travel
  SimDrive d(c);
  ASSERT_EQ(d.sdo_write(0x6098, 0, 4, 1), 0u);
  ASSERT_EQ(d.sdo_write(0x6099, 1, 40'000, 4), 0u);
  ASSERT_EQ(d.sdo_write(0x6099, 2, 4'000, 4), 0u);
  d.enable(Mode::Homing);
  d.cw(0x1F);
  ASSERT_TRUE(d.sync_until([&] { return decode_homing(d.model.statusword()) == HomingStatus::ErrorStopped; }, 10'000));
  EXPECT_FALSE(d.model.homed());
  EXPECT_STREQ(d.model.homing_error(), "the positive limit switch was reached while homing");
}

TEST(Cia402Sim, UnsupportedHomingMethodIsRefused) {
  SimDrive d;
  EXPECT_EQ(d.sdo_write(0x6098, 0, 7, 1), 0x06090030u);
  EXPECT_EQ(d.sdo_write(0x6098, 0, static_cast<uint8_t>(-1), 1), 0x06090030u);
  EXPECT_EQ(d.sdo_write(0x6098, 0, 34, 1), 0u);
}

// ---------------------------------------------------------------- probes

TEST(Cia402Sim, TouchProbeLatchesTheEncoderWhereTheProbeSwitched) {
  DriveSimConfig c = base_config();
  c.plant.probe_position = -0.0051234;  // active at or below
  SimDrive d(c);
  d.enable();
  d.od.set<uint16_t>({0x60B8, 0}, tp::kEnable | tp::kRising | tp::kFalling);  // probe input, single shot
  d.sync();
  EXPECT_EQ(d.od.get<uint16_t>({0x60B9, 0}) & 0x07, tp::kStatusEnabled);
  d.move_to(-8, 40);  // crosses -5.1234 mm at 40 mm/s: 80 increments per ms
  const uint16_t status = d.od.get<uint16_t>({0x60B9, 0});
  EXPECT_TRUE(status & tp::kStatusRisingStored);
  EXPECT_FALSE(status & tp::kStatusFallingStored);  // single shot: the first event only
  EXPECT_TRUE(status & tp::kStatusInputLevel);
  const double latched_mm = d.od.get<int32_t>({0x60BA, 0}) / kCountsPerMm;
  EXPECT_NEAR(latched_mm, -5.1234, 1.0 / kCountsPerMm);  // one increment, where sampling per SYNC is off by up to 40 um
  // Re-armed by clearing and setting the enable bit: the falling edge on the way back.
  d.od.set<uint16_t>({0x60B8, 0}, 0);
  d.sync();
  EXPECT_EQ(d.od.get<uint16_t>({0x60B9, 0}) & 0x07, 0);
  d.od.set<uint16_t>({0x60B8, 0}, tp::kEnable | tp::kFalling);
  d.sync();
  d.move_to(0, 40);
  EXPECT_TRUE(d.od.get<uint16_t>({0x60B9, 0}) & tp::kStatusFallingStored);
  EXPECT_NEAR(d.od.get<int32_t>({0x60BB, 0}) / kCountsPerMm, -5.1234, 1.0 / kCountsPerMm);
}

TEST(Cia402Sim, TouchProbeTwoLatchesTheEncoderZeroPulse) {
  SimDrive d;
  d.enable();
  d.od.set<uint16_t>({0x60B8, 0}, static_cast<uint16_t>((tp::kEnable | tp::kSourceZeroPulse | tp::kRising) << 8));
  d.sync();
  d.move_to(7, 30);  // passes the zero pulses at 1.3 and 6.3 mm: single shot keeps the first
  EXPECT_TRUE(d.od.get<uint16_t>({0x60B9, 0}) & (tp::kStatusRisingStored << 8));
  EXPECT_NEAR(d.od.get<int32_t>({0x60BC, 0}) / kCountsPerMm, 1.3, 1.0 / kCountsPerMm);
}

// ---------------------------------------------------------------- limits, errors

TEST(Cia402Sim, FollowingErrorWindowSetsBit13ThenFaults) {
  DriveSimConfig c = base_config();
  c.gains.position_gain = 2;  // far too soft
  c.gains.velocity_ff = 0;
  c.gains.torque_ff = 0;
  SimDrive d(c);
  ASSERT_EQ(d.sdo_write(0x6065, 0, 2000, 4), 0u);  // 1 mm
  ASSERT_EQ(d.sdo_write(0x6066, 0, 50, 2), 0u);
  d.enable();
  bool saw_bit13 = false;
  double p = 0;
  for (int i = 0; i < 2000 && d.state() == State::OperationEnabled; ++i) {
    p += 0.02;
    d.target(std::llround(p * kCountsPerMm));
    d.sync();
    saw_bit13 = saw_bit13 || (d.model.statusword() & sw::kBit13);
  }
  EXPECT_TRUE(saw_bit13);
  EXPECT_TRUE(d.sync_until([&] { return d.state() == State::Fault; }, 1000));
  EXPECT_EQ(d.model.error_code(), err::kFollowingError);
  ASSERT_FALSE(d.emcy.empty());
  EXPECT_EQ(d.emcy.front(), err::kFollowingError);
}

// Late set-points caught up at once, or a master that jumps, give the drive
// a target step. At the torque limit the velocity loop's integral must not
// wind up: the drive clamped its command at 0x6072 (= the power stage's
// current limit) before the plant, so the plant never reported limiting and
// the integral ran on; each reversal swung the axis out further, the
// following-error fault came and its ramp ran under the same loop (this
// step took the axis to -140 mm; the VM test's X went to -654 mm).
TEST(Cia402Sim, ASetPointStepAtTheTorqueLimitSettlesWithoutWindingUp) {
  DriveSimConfig c = base_config();  // the VM test's drives
  c.step_s = 200e-6;
  c.gains.velocity_bandwidth_hz = 100;
  SimDrive d(c);
  ASSERT_EQ(d.sdo_write(0x60C2, 1, 10, 1), 0u);  // a 10 ms cycle, as in the VM test
  ASSERT_EQ(d.sdo_write(0x60C2, 2, 0xFD, 1), 0u);
  d.period_ns = 10'000'000;
  d.enable();
  d.syncs(20);
  const int64_t from = d.position();
  const int64_t to = from + 3000;  // 1.5 mm in one period: 150 mm/s, under 0x6080
  d.target(to);
  int limited = 0;
  double lo = 1e18, hi = -1e18;
  for (int i = 0; i < 100; ++i) {
    d.sync();
    if (d.model.statusword() & sw::kInternalLimit) ++limited;  // bit 11: at the current limit
    lo = std::min(lo, static_cast<double>(d.position()));
    hi = std::max(hi, static_cast<double>(d.position()));
  }
  EXPECT_GT(limited, 0) << "the step must reach the torque limit (bit 11) for this test to mean anything";
  EXPECT_EQ(d.state(), State::OperationEnabled);
  EXPECT_GE(lo, from - 20.0);  // never back beyond where it started
  EXPECT_LE(hi, to + 0.5 * 3000);  // overshoot below half the step
  EXPECT_NEAR(static_cast<double>(d.position()), static_cast<double>(to), 2.0);
}

// 0x6080 (rpm) and 0x607F (increments/s) bound the CSP demand: a target
// further away than one period allows is approached at the limit, with
// "internal limit active" (bit 11), and reached without a fault.
TEST(Cia402Sim, ATargetBeyondTheVelocityLimitIsApproachedAtTheLimit) {
  SimDrive d;
  ASSERT_EQ(d.sdo_write(0x6080, 0, 600, 4), 0u);  // 600 rpm: 50 mm/s with the 5 mm screw
  d.enable();
  d.syncs(20);
  const int64_t to = d.position() + 20 * static_cast<int64_t>(kCountsPerMm);  // 20 mm at once
  d.target(to);
  double fastest = 0;
  int limited = 0, syncs = 0;
  while (syncs < 1000 && std::llabs(d.position() - to) > 2) {
    const double before = d.model.demand();
    d.sync();
    ++syncs;
    fastest = std::max(fastest, std::fabs(d.model.demand() - before) / kCountsPerMm / 0.001);
    if (d.model.statusword() & sw::kInternalLimit) ++limited;
  }
  EXPECT_LE(fastest, 50.0 * 1.0001);  // mm/s of the demand
  EXPECT_NEAR(syncs, 400, 30);         // 20 mm at 50 mm/s
  EXPECT_GT(limited, 350);
  EXPECT_EQ(d.state(), State::OperationEnabled);
  d.syncs(50);
  EXPECT_FALSE(d.model.statusword() & sw::kInternalLimit);
  EXPECT_NEAR(static_cast<double>(d.position()), static_cast<double>(to), 2.0);
}

// A following-error fault means the axis is not where the demand is; the
// fault reaction's ramp starts from the axis, not from the old demand (else
// a load that breaks loose is pulled to the demand at full torque first).
TEST(Cia402Sim, AFollowingErrorFaultStopsWhereTheAxisIsNotAtTheDemand) {
  SimDrive d;
  ASSERT_EQ(d.sdo_write(0x6065, 0, 2000, 4), 0u);  // 1 mm
  ASSERT_EQ(d.sdo_write(0x6066, 0, 10, 2), 0u);
  d.enable();
  d.model.set_jam_force(1e6);  // the table is stuck
  double p = d.position() / kCountsPerMm;
  for (int i = 0; i < 500 && d.state() == State::OperationEnabled; ++i) {
    p += 0.05;  // 50 mm/s
    d.target(std::llround(p * kCountsPerMm));
    d.sync();
  }
  ASSERT_NE(d.state(), State::OperationEnabled);
  ASSERT_EQ(d.model.error_code(), err::kFollowingError);
  const double stuck_at = d.table_mm();
  d.model.set_jam_force(0);  // and breaks loose during the fault reaction
  ASSERT_TRUE(d.sync_until([&] { return d.state() == State::Fault; }, 1000));
  d.syncs(50);
  EXPECT_NEAR(d.table_mm(), stuck_at, 0.05);
}

TEST(Cia402Sim, LimitSwitchStopsMotionIntoItAndSetsTheInternalLimitBit) {
  SimDrive d;
  d.enable();
  d.move_to(45, 20);  // the positive limit switch is at 40 mm
  EXPECT_LT(d.table_mm(), 41.0);
  EXPECT_TRUE(d.model.statusword() & sw::kInternalLimit);
  EXPECT_TRUE(d.od.get<uint32_t>({0x60FD, 0}) & din::kPositiveLimit);
  d.move_to(30, 20);  // away from it is allowed
  EXPECT_NEAR(d.table_mm(), 30, 0.01);
}

TEST(Cia402Sim, AReversedMotorSeesTheTablesPlusSwitchAsItsNegativeLimitAndStopsAtIt) {
  DriveSimConfig c = base_config();
  c.motor_reversed = true;  // positive increments move the table towards minus
  SimDrive d(c);
  d.enable();
  d.move_to(-45, 20);  // the table runs towards its + switch at 40 mm
  EXPECT_GT(d.table_mm(), 39.0);
  EXPECT_LT(d.table_mm(), 41.0);
  EXPECT_TRUE(d.od.get<uint32_t>({0x60FD, 0}) & din::kNegativeLimit);
  EXPECT_FALSE(d.od.get<uint32_t>({0x60FD, 0}) & din::kPositiveLimit);
  d.move_to(-30, 20);  // away from it is allowed
  EXPECT_NEAR(d.table_mm(), 30, 0.01);
}

TEST(Cia402Sim, SwitchesActiveLowReadInvertedButStillStopTheDrive) {
  DriveSimConfig c = base_config();
  c.switches_active_low = true;
  SimDrive d(c);
  d.enable();
  d.syncs(2);
  const uint32_t all = din::kNegativeLimit | din::kPositiveLimit | din::kHomeSwitch;
  EXPECT_EQ(d.od.get<uint32_t>({0x60FD, 0}) & all, all);  // none actuated at 0
  d.move_to(45, 20);
  EXPECT_LT(d.table_mm(), 41.0);
  EXPECT_EQ(d.od.get<uint32_t>({0x60FD, 0}) & all, din::kNegativeLimit);  // + limit and home actuated
}

TEST(Cia402Sim, SoftwareLimitsClampTheDemand) {
  SimDrive d;
  ASSERT_EQ(d.sdo_write(0x607D, 1, static_cast<uint32_t>(-10'000), 4), 0u);
  ASSERT_EQ(d.sdo_write(0x607D, 2, 20'000, 4), 0u);  // +10 mm
  d.enable();
  d.move_to(15, 20);
  EXPECT_NEAR(d.table_mm(), 10.0, 0.01);
  EXPECT_TRUE(d.model.statusword() & sw::kInternalLimit);
}

TEST(Cia402Sim, EncoderLossFaultsAndFreezesThePosition) {
  SimDrive d;
  d.enable();
  d.model.set_encoder_lost(true);
  d.sync();
  EXPECT_EQ(d.state(), State::Fault);
  EXPECT_EQ(d.model.error_code(), err::kEncoder);
  d.cw(0x00);
  d.sync();
  d.cw(0x80);
  d.sync();
  EXPECT_EQ(d.state(), State::Fault);  // the encoder is still gone
}

TEST(Cia402Sim, RefusedWritesAbortWithDeviceState) {
  SimDrive d;
  d.model.set_refuse_writes(true);
  EXPECT_EQ(d.sdo_write(0x6098, 0, 4, 1), 0x08000022u);
  EXPECT_EQ(d.sdo_write(0x607C, 0, 1, 4), 0x08000022u);
  d.model.set_refuse_writes(false);
  EXPECT_EQ(d.sdo_write(0x607C, 0, 1, 4), 0u);
}

// ---------------------------------------------------------------- plant

TEST(Cia402Plant, BacklashLetsTheMotorTurnBeforeTheTableFollows) {
  PlantConfig c = base_config().plant;
  c.backlash_m = 20e-6;
  Plant p(c);
  // Push the motor forward, then backward: the table moves less than the
  // nut by the backlash at the reversal.
  auto run = [&](double torque, int steps) {
    for (int i = 0; i < steps; ++i) p.step(20e-6, torque, true);
  };
  run(0.3, 2000);
  run(0.0, 5000);
  const double nut0 = p.nut_position(), table0 = p.table_position();
  run(-0.3, 2000);
  run(0.0, 5000);
  const double nut_moved = nut0 - p.nut_position(), table_moved = table0 - p.table_position();
  EXPECT_GT(nut_moved, 1e-3);
  EXPECT_NEAR(nut_moved - table_moved, 20e-6, 2e-6);
}

TEST(Cia402Plant, PitchErrorShowsInTheTrueTablePositionOnly) {
  PlantConfig c = base_config().plant;
  c.pitch_points = 2;
  c.pitch_at[0] = 0;
  c.pitch_error[0] = 0;
  c.pitch_at[1] = 0.1;
  c.pitch_error[1] = 10e-6;  // +10 um over 100 mm
  Plant p(c);
  EXPECT_NEAR(p.pitch_error_at(0.05), 5e-6, 1e-12);
  while (p.nut_position() < 0.05) p.step(20e-6, 0.5, true);
  while (p.motor_velocity() > 0) p.step(20e-6, -0.5, true);
  const double nominal = c.start_position + p.motor_angle() * c.lead_m / (2 * M_PI);
  EXPECT_NEAR(p.table_position() - nominal, p.pitch_error_at(nominal), 1e-9);
}

TEST(Cia402Plant, CoulombFrictionHoldsAgainstSmallTorques) {
  Plant p(base_config().plant);
  const double breakaway = base_config().plant.motor_coulomb + base_config().plant.load_coulomb * 0.005 / (2 * M_PI);
  for (int i = 0; i < 1000; ++i) p.step(20e-6, breakaway * 0.9, true);
  EXPECT_EQ(p.motor_velocity(), 0.0);
  for (int i = 0; i < 1000; ++i) p.step(20e-6, breakaway * 1.5, true);
  EXPECT_GT(p.motor_velocity(), 0.0);
}

TEST(Cia402Plant, CurrentLimitCapsTheTorque) {
  PlantConfig c = base_config().plant;
  c.max_current = 2;
  Plant p(c);
  for (int i = 0; i < 500; ++i) p.step(20e-6, 100.0, true);
  EXPECT_NEAR(p.torque(), c.torque_constant * 2, 1e-6);
  EXPECT_TRUE(p.current_limited());
  for (int i = 0; i < 10; ++i) p.step(20e-6, 100.0, false);
  EXPECT_EQ(p.torque(), 0.0);  // power stage off
}

TEST(Cia402Sim, RunsWithoutAllocating) {
  SimDrive d;
  d.enable();
  d.trace.reserve(10'000);
  d.emcy.reserve(10);
  cnc::testing::ScopedAllocationCheck check;
  d.model.set_temperature_offset(0);
  double p = 0;
  for (int i = 0; i < 2000; ++i) {
    p += 0.01;
    d.target(std::llround(p * kCountsPerMm));
    d.sync();
  }
  d.model.inject_overcurrent();
  d.syncs(5);
  if (cnc::testing::AllocationCounter::available()) {
    EXPECT_EQ(check.allocations(), 0u);
  }
}
