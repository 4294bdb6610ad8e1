// The master side of the state machine against a scripted drive: for every
// state the drive reports, what the master commands, with and without the
// wish to enable; invalid statuswords; the enable timeout; the fault reset
// edge. A fake link holds the process image in memory.
#include <gtest/gtest.h>

#include <array>
#include <map>

#include "cia402/drive.hpp"
#include "core/util/messages.hpp"

using namespace cnc;
using namespace cnc::cia402;

namespace {

class FakeLink final : public DriveLink {
 public:
  FakeLink() {
    place(false, obj::kControlword, 0, 16);
    place(false, obj::kTargetPosition, 2, 32);
    place(false, obj::kModes, 6, 8);
    place(true, obj::kStatusword, 0, 16);
    place(true, obj::kPositionActual, 2, 32);
    place(true, obj::kModesDisplay, 6, 8);
    place(true, obj::kErrorCode, 7, 16);
    // The touch probe, as on configs/sim: status and position in two PDOs.
    place(false, obj::kTouchProbeFunction, 8, 16);
    place(true, obj::kTouchProbeStatus, 9, 16);
    place(true, obj::kTouchProbe1Rising, 16, 32);
  }
  const std::string& name() const noexcept override { return name_; }
  bool has_device(int a) const noexcept override { return a == 1; }
  Slot output(int, Object o) const noexcept override { return find(false, o); }
  Slot input(int, Object o) const noexcept override { return find(true, o); }
  ConfigResult read_wait(int, Object, unsigned) override { return {}; }
  ConfigResult write_wait(int, Object, uint64_t, unsigned) override { return {}; }
  int64_t cycle_ns() const noexcept override { return 1'000'000; }
  LinkHealth health(int) const noexcept override {
    LinkHealth h;
    h.operational = true;
    h.inputs_fresh = fresh;
    return h;
  }
  int request_read(int, Object) noexcept override { return -1; }
  int request_write(int, Object, uint32_t, unsigned) noexcept override { return -1; }
  bool poll(int, AcyclicResult&) noexcept override { return false; }
  // Arrival order: the status (bytes 0-15) and the probe position (16-19)
  // as two frames, each stamped when the test says it arrived.
  uint64_t input_sequence(const Slot& s) const noexcept override {
    return s.bit_offset >= 16 * 8 ? position_frame : status_frame;
  }
  uint64_t status_frame = 1, position_frame = 1;

  void drive_reports(uint16_t statusword, int32_t position = 0, Mode display = Mode::CyclicSyncPosition,
                     uint16_t error = 0) {
    write_slot<uint16_t>(find(true, obj::kStatusword), statusword);
    write_slot<int32_t>(find(true, obj::kPositionActual), position);
    write_slot<int8_t>(find(true, obj::kModesDisplay), static_cast<int8_t>(display));
    write_slot<uint16_t>(find(true, obj::kErrorCode), error);
  }
  void probe_reports(uint16_t status) { write_slot<uint16_t>(find(true, obj::kTouchProbeStatus), status); }
  void probe_position(int32_t counts) { write_slot<int32_t>(find(true, obj::kTouchProbe1Rising), counts); }
  uint16_t probe_function() const { return read_slot<uint16_t>(find(false, obj::kTouchProbeFunction)); }
  uint16_t controlword() const { return read_slot<uint16_t>(find(false, obj::kControlword)); }
  int32_t target() const { return read_slot<int32_t>(find(false, obj::kTargetPosition)); }
  int8_t mode() const { return read_slot<int8_t>(find(false, obj::kModes)); }
  bool fresh = true;  // the bus says this cycle's inputs answered the last one

 private:
  void place(bool in, Object o, uint16_t byte, uint8_t bits) {
    (in ? in_map_ : out_map_)[key(o)] = Slot{(in ? in_ : out_).data(), static_cast<uint16_t>(byte * 8), bits};
  }
  static uint32_t key(Object o) { return uint32_t{o.index} << 8 | o.sub; }
  Slot find(bool in, Object o) const {
    const auto& m = in ? in_map_ : out_map_;
    const auto it = m.find(key(o));
    return it == m.end() ? Slot{} : it->second;
  }
  std::string name_ = "fake";
  mutable std::array<uint8_t, 32> in_{}, out_{};
  std::map<uint32_t, Slot> in_map_, out_map_;
};

struct Master {
  explicit Master(int stale_limit = 3, bool probe = false) : drive(config(stale_limit, probe), link, &messages) {}
  static DriveConfig config(int stale_limit = 3, bool probe = false) {
    DriveConfig c;
    c.stale_limit = stale_limit;
    c.name = "x-axis";
    c.source = "cia402.0.drive.00";
    c.address = 1;
    c.scaling = Scaling::from_mechanics(10000, 1, 1, 5, false);
    c.enable_timeout_ns = 50'000'000;
    c.fault_reset_holdoff_ns = 100'000'000;
    c.probe = probe;
    return c;
  }
  // One cycle with the drive reporting `sw`; returns the controlword sent.
  uint16_t cycle(uint16_t sw, int32_t pos = 0) {
    link.drive_reports(sw, pos);
    t += 1'000'000;
    drive.read(t, cmd, fb);
    drive.write(t, cmd, fb);
    return link.controlword();
  }
  bool has_message(const std::string& part) {
    Message m;
    while (messages.pop(m)) log += std::string(m.text.c_str()) + "\n";
    return log.find(part) != std::string::npos;
  }
  FakeLink link;
  MessageQueue messages;
  Drive drive;
  DriveCommand cmd;
  DriveFeedback fb;
  int64_t t = 0;
  std::string log;
};

constexpr uint16_t kNotReady = 0x0200, kSod = 0x0250, kRtso = 0x0231, kSo = 0x0233, kOe = 0x1237, kQsa = 0x0217,
                   kFra = 0x021F, kFault = 0x0218;

}  // namespace

TEST(Cia402MasterStates, CommandsForEveryStateWhenEnabling) {
  Master m;
  m.cmd.enable = true;
  EXPECT_EQ(m.cycle(kNotReady), cw::kDisableVoltage);  // waits for T1
  EXPECT_EQ(m.cycle(kSod), cw::kShutdown);             // T2
  EXPECT_EQ(m.cycle(kRtso), cw::kSwitchOnCmd);         // T3
  EXPECT_EQ(m.cycle(kSo, 4321), cw::kEnableOperationCmd);  // T4, with target := actual
  EXPECT_EQ(m.link.target(), 4321);
  EXPECT_EQ(m.cycle(kOe, 4321), cw::kEnableOperationCmd);
  EXPECT_TRUE(m.fb.enabled);
  EXPECT_EQ(m.cycle(kFra), cw::kDisableVoltage);       // the drive's own reaction: wait
  EXPECT_EQ(m.cycle(kFault), cw::kDisableVoltage);     // no reset without an edge
}

TEST(Cia402MasterStates, CommandsForEveryStateWhenDisabling) {
  Master m;
  m.cmd.enable = false;
  EXPECT_EQ(m.cycle(kSod), cw::kDisableVoltage);
  EXPECT_EQ(m.cycle(kRtso), cw::kDisableVoltage);  // T7
  EXPECT_EQ(m.cycle(kSo), cw::kDisableVoltage);    // T10
  EXPECT_EQ(m.cycle(kOe), cw::kQuickStopCmd);      // T11: stop on the ramp first
  EXPECT_EQ(m.cycle(kQsa), cw::kQuickStopCmd);     // T12 comes from the drive (option 0-4)...
  for (int i = 0; i < 2100; ++i) m.cycle(kQsa);    // ... or after the quick-stop time-out:
  EXPECT_EQ(m.cycle(kQsa), cw::kDisableVoltage);   // T12 by disable voltage
}

TEST(Cia402MasterStates, FollowsTheCommandOnlyOnceTheDriveFollows) {
  Master m;
  m.cmd.enable = true;
  m.cycle(kSod, 1000);
  m.cycle(kRtso, 1000);
  m.cycle(kSo, 1000);
  m.cmd.pos_cmd = 1.0;  // 2000 increments: motion moved on already
  m.cycle(kOe & ~sw::kBit12, 1000);  // operation enabled, but bit 12 says "target ignored"
  EXPECT_EQ(m.link.target(), 1000);
  EXPECT_FALSE(m.fb.enabled);
  m.cycle(kOe, 1000);
  EXPECT_EQ(m.link.target(), 2000);
  EXPECT_TRUE(m.fb.enabled);
}

TEST(Cia402MasterStates, AnInvalidStatuswordIsReportedNeverMapped) {
  Master m;
  m.cmd.enable = true;
  EXPECT_EQ(m.cycle(0x0201), cw::kDisableVoltage);
  EXPECT_EQ(m.fb.state, State::Invalid);
  EXPECT_TRUE(m.has_message("statusword 0x0201 matches no CiA 402 state"));
}

TEST(Cia402MasterStates, EnableTimesOutNamingTheStateReached) {
  Master m;
  m.cmd.enable = true;
  for (int i = 0; i < 60; ++i) m.cycle(kRtso);  // the drive never switches on
  EXPECT_TRUE(m.has_message("did not reach operation enabled within 50 ms (stuck in ready to switch on"));
  m.cycle(kRtso);
  EXPECT_TRUE(m.fb.amp_fault);
  EXPECT_EQ(m.cycle(kRtso), cw::kDisableVoltage);  // it stops asking
  m.cmd.enable = false;
  m.cycle(kRtso);
  EXPECT_FALSE(m.fb.amp_fault);
  m.cmd.enable = true;
  EXPECT_EQ(m.cycle(kRtso), cw::kSwitchOnCmd);  // a new enable tries again
}

TEST(Cia402MasterStates, FaultResetIsAnEdgeOnAnEnableOrResetEdgeWithHoldOff) {
  Master m;
  m.cycle(kFault);
  m.cycle(kFault);
  EXPECT_FALSE(m.fb.amp_fault);  // motion is disabled: nothing to tell it
  m.cmd.enable = true;           // rising edge
  EXPECT_EQ(m.cycle(kFault), cw::kDisableVoltage);  // bit 7 low first ...
  EXPECT_EQ(m.cycle(kFault), cw::kDisableVoltage);
  EXPECT_EQ(m.cycle(kFault), cw::kFaultResetCmd);   // ... then high: the edge
  EXPECT_FALSE(m.fb.amp_fault);                     // while the reset runs
  EXPECT_EQ(m.cycle(kSod), cw::kShutdown);          // T15 done: enabling
  // Faults again at once: the fault-reset input's edge is inside the hold-off.
  m.cycle(kFault);
  m.cmd.fault_reset = true;
  EXPECT_EQ(m.cycle(kFault), cw::kDisableVoltage);
  EXPECT_TRUE(m.has_message("fault reset refused"));
  m.cmd.fault_reset = false;
  for (int i = 0; i < 120; ++i) EXPECT_EQ(m.cycle(kFault) & cw::kFaultReset, 0);  // no retry by itself
  m.cmd.fault_reset = true;
  m.cycle(kFault);
  m.cycle(kFault);
  EXPECT_EQ(m.cycle(kFault), cw::kFaultResetCmd);  // past the hold-off: reset
}

TEST(Cia402MasterStates, WritesTheConfiguredModeAndWaitsForItsDisplay) {
  Master m;
  m.link.drive_reports(kSod, 0, Mode::None);
  m.t += 1'000'000;
  m.drive.read(m.t, m.cmd, m.fb);
  m.drive.write(m.t, m.cmd, m.fb);
  EXPECT_EQ(m.link.mode(), 8);
  EXPECT_TRUE(m.fb.switching_mode);
  m.link.drive_reports(kSod, 0, Mode::CyclicSyncPosition);
  m.t += 1'000'000;
  m.drive.read(m.t, m.cmd, m.fb);
  m.drive.write(m.t, m.cmd, m.fb);
  EXPECT_FALSE(m.fb.switching_mode);
}

namespace {

// A drive at operation enabled, following the demand 20 increments a cycle
// a few cycles behind (the transport and the drive's interpolation), as a
// CSP drive does.
struct Moving : Master {
  explicit Moving(int stale_limit) : Master(stale_limit) {
    cmd.enable = true;
    cycle(kSod);
    cycle(kRtso);
    cycle(kSo);
    for (int i = 0; i < 10; ++i) step(true);
  }
  // One cycle: the demand moves on; a fresh sample follows it, a stale one
  // repeats the last.
  void step(bool fresh) {
    link.fresh = fresh;
    if (fresh) reported = demand_two_ago - 10;
    demand_two_ago = demand_one_ago;
    demand_one_ago = target_counts;
    target_counts += 20;
    cmd.pos_cmd = target_counts / 2000.0;
    cycle(kOe, static_cast<int32_t>(reported));
  }
  int64_t target_counts = 0, demand_one_ago = 0, demand_two_ago = 0, reported = 0;
};

}  // namespace

TEST(Cia402MasterStates, StaleInputsWithinTheBudgetShowTheDemandLessTheLastLag) {
  Moving m(3);
  const double fresh_ferror = m.fb.ferror;
  EXPECT_GT(fresh_ferror, 0.0);
  for (int i = 0; i < 3; ++i) {
    const double before = m.fb.pos_fb;
    m.step(false);
    EXPECT_TRUE(m.fb.link_ok) << "stale cycle " << i + 1 << " is within STALE_LIMIT = 3";
    EXPECT_FALSE(m.fb.amp_fault);
    EXPECT_NEAR(m.fb.pos_fb - before, 20 / 2000.0, 1e-9) << "the feedback of a moving axis is not frozen";
    EXPECT_NEAR(m.fb.ferror, fresh_ferror, 1e-9) << "no following error grows from stale samples";
  }
  m.step(true);
  EXPECT_TRUE(m.fb.link_ok);
  EXPECT_FALSE(m.has_message("no fresh feedback"));
}

TEST(Cia402MasterStates, StaleInputsPastTheBudgetStopTheAxisSayingWhy) {
  Moving m(3);
  for (int i = 0; i < 3; ++i) m.step(false);
  ASSERT_TRUE(m.fb.link_ok);
  m.step(false);
  EXPECT_FALSE(m.fb.link_ok) << "a fourth stale cycle is past STALE_LIMIT = 3";
  EXPECT_TRUE(m.fb.amp_fault) << "motion sees the amplifier fault and stops";
  EXPECT_TRUE(m.has_message("no fresh feedback for 4 cycles on fake (STALE_LIMIT = 3)"));
  EXPECT_NE(std::string(m.drive.fault_text()).find("feedback stale for 4 cycles on fake"), std::string::npos);
  m.step(true);
  EXPECT_TRUE(m.fb.link_ok) << "fresh inputs make the link ok again (motion needs a new enable)";
}

TEST(Cia402MasterStates, StaleLimitZeroLeavesTheBudgetToTheBus) {
  Moving m(0);
  for (int i = 0; i < 50; ++i) m.step(false);
  EXPECT_TRUE(m.fb.link_ok);
  EXPECT_FALSE(m.has_message("no fresh feedback"));
}

// A latch's position may travel in another PDO than the status bit that
// reports it, rate-limited by its inhibit time (configs/sim: 0x60B9 in
// TPDO2, 0x60BA in TPDO3): the position is taken only from a frame no
// older than the status frame that showed the latch; meanwhile the probe
// input is on but no position is reported.
TEST(Cia402MasterStates, ATouchProbePositionIsTakenOnlyFromAFrameAfterTheLatchStatus) {
  Master m(3, true);
  m.link.probe_position(1111);  // an earlier latch's value
  m.cycle(kSod);
  EXPECT_EQ(m.link.probe_function() & tp::kEnable, tp::kEnable) << "armed";
  m.link.probe_reports(tp::kStatusEnabled);
  m.cycle(kSod);
  m.cycle(kSod);
  // The status frame (arrival 10) says: latched. The position slot still
  // holds the old value from frame 5.
  m.link.status_frame = 10;
  m.link.position_frame = 5;
  m.link.probe_reports(tp::kStatusEnabled | tp::kStatusRisingStored);
  m.cycle(kSod);
  EXPECT_TRUE(m.fb.probe_input);
  EXPECT_EQ(m.fb.probe_count, 0u) << "not from the stale 1111";
  m.cycle(kSod);
  EXPECT_EQ(m.fb.probe_count, 0u);
  // Its PDO arrives (frame 12) with the latched value.
  m.link.position_frame = 12;
  m.link.probe_position(25000);
  m.cycle(kSod);
  EXPECT_EQ(m.fb.probe_count, 1u);
  EXPECT_DOUBLE_EQ(m.fb.probe_position, 25000 * 5.0 / 10000);
  // Status and position in one frame: taken at once.
  Master same(3, true);
  same.cycle(kSod);
  same.link.probe_reports(tp::kStatusEnabled);
  same.cycle(kSod);
  same.cycle(kSod);
  same.link.status_frame = same.link.position_frame = 7;
  same.link.probe_position(4000);
  same.link.probe_reports(tp::kStatusEnabled | tp::kStatusRisingStored);
  same.cycle(kSod);
  EXPECT_EQ(same.fb.probe_count, 1u);
  EXPECT_DOUBLE_EQ(same.fb.probe_position, 4000 * 5.0 / 10000);
}
