// Step 7's loop response end to end (label slow): `cnc-commission axis X
// response` on a random simulated axis, on the response configuration it
// brings up itself (cncd, the CANopen master, the simulated drive), the
// gains read and written by SDO over the shared virtual bus. A higher
// velocity-loop gain written to 0x60F9:1 must show as a faster step and a
// higher -3 dB bandwidth, on the velocity loop and on the position loop.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>

#include "commission/response.hpp"
#include "commission/steps.hpp"
#include "commission/tuning.hpp"
#include "sim/cia402/random_machine.hpp"
#include "tests/commission/e2e_support.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission {
namespace {

namespace csim = cnc::cia402::sim;

class ResponseE2e : public ::testing::Test {
 protected:
  void SetUp() override {
    bin_ = testing::binary_dir() / "bin";
    for (const char* p : {"cncd", "cnc", "halcmd", "cnc-commission"})
      if (!std::filesystem::exists(bin_ / p)) GTEST_SKIP() << p << " is not built";
    setenv("CNC_INSTANCE", testing::unique_name("resp").c_str(), 1);
    setenv("CNC_NO_REALTIME", "1", 1);
  }
  void TearDown() override { (void)testing::run_shell(e2e::cnc_cmd("shutdown >/dev/null 2>&1")); }
  testing::CommandOutput cc(const std::string& args) {
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = testing::run_shell("'" + (bin_ / "cnc-commission").string() + "' --state '" + state_.string() + "' " +
                                      args + " 2>&1");
    std::printf("$ cnc-commission %s  (%.1f s, status %d)\n%s", args.c_str(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), r.code, r.text.c_str());
    std::fflush(stdout);
    return r;
  }
  // A random one-axis machine and a state with X assigned on it, its
  // travel entered (-10..10 mm around where the table powers up).
  void write_machine() {
    std::filesystem::create_directories(m_);
    const csim::RandomMachine m = csim::make_random_machine(e2e::machine_seed(), {1}, "virtual:" + testing::unique_name("resp"));
    e2e::write_machine_files(m_, m);
    State s;
    s.interface = m.interface;
    ScannedNode n;
    n.node_id = 1;
    n.cia402 = true;
    n.encoder_increments = static_cast<uint32_t>(m.axes[0].encoder_counts);
    s.nodes.push_back(n);
    assign_axis(s, 'X', 0, 1);
    set_scaling(s, 'X', 5.0);  // the scaling may be wrong: command and feedback share it
    s.axis('X')->min_limit = -10;
    s.axis('X')->max_limit = 10;
    s.axis('X')->limits_source = "entered";
    e2e::include_machine_files(s);
    save_state(s, state_);
  }
  // `loop_args`: the velocity loop at 4 mm/s unless given.
  AxisResponse measure(const std::string& gain, const std::string& loop_args = "--amplitude 4") {
    const auto r = cc("axis X response --bring-up '" + m_.string() + "' --record '" + (dir_ / "rec").string() + "' " + loop_args +
                      (gain.empty() ? "" : " --velocity-gain " + gain));
    EXPECT_EQ(r.code, 0) << r.text << "\ncncd log:\n" << e2e::read_text(m_ / "cncd.log");
    const State s = load_state(state_);
    if (!s.axis('X')->response) {
      ADD_FAILURE() << "no response in the state";
      return {};
    }
    return *s.axis('X')->response;
  }

  std::filesystem::path bin_;
  testing::TempDir dir_;
  std::filesystem::path m_ = dir_ / "m", state_ = dir_ / "state.json";
};

TEST_F(ResponseE2e, AHigherVelocityGainWrittenTo60F9GivesAFasterStepAndAHigherBandwidth) {
  write_machine();

  // The drive's own gains (200 Hz): read, and recorded.
  const AxisResponse defaults = measure("");
  ASSERT_TRUE(defaults.skipped.empty()) << defaults.skipped;
  ASSERT_GT(defaults.gains.velocity_gain, 0u);
  ASSERT_TRUE(defaults.step && defaults.chirp);
  EXPECT_TRUE(std::filesystem::exists(defaults.step->csv));
  EXPECT_EQ(e2e::read_text(defaults.chirp->csv).substr(0, e2e::read_text(defaults.chirp->csv).find('\n')),
            kResponseCsvHeader);
  // A tenth and a quarter of them: velocity loops of about 20 and 50 Hz.
  const uint32_t k = defaults.gains.velocity_gain;
  const AxisResponse low = measure(std::to_string(k / 10));
  const AxisResponse high = measure(std::to_string(k / 4));
  ASSERT_EQ(low.gains.velocity_gain, k / 10) << "0x60F9:1 read back after the write";
  ASSERT_EQ(high.gains.velocity_gain, k / 4);
  ASSERT_TRUE(low.step && low.chirp && high.step && high.chirp);
  std::printf("gain %u: rise %.2f ms, overshoot %.1f %%, bandwidth %.1f Hz%s\n", k / 10, low.step->rise_time_s * 1e3,
              low.step->overshoot_pct, low.chirp->bandwidth_hz, low.chirp->bandwidth_above ? " (above)" : "");
  std::printf("gain %u: rise %.2f ms, overshoot %.1f %%, bandwidth %.1f Hz%s\n", k / 4, high.step->rise_time_s * 1e3,
              high.step->overshoot_pct, high.chirp->bandwidth_hz, high.chirp->bandwidth_above ? " (above)" : "");
  std::printf("gain %u: rise %.2f ms, overshoot %.1f %%, bandwidth %.1f Hz%s\n", k, defaults.step->rise_time_s * 1e3,
              defaults.step->overshoot_pct, defaults.chirp->bandwidth_hz, defaults.chirp->bandwidth_above ? " (above)" : "");
  EXPECT_FALSE(low.chirp->bandwidth_above) << "the low gain's bandwidth must lie inside the sweep";
  EXPECT_GT(high.chirp->bandwidth_hz, 1.3 * low.chirp->bandwidth_hz);
  EXPECT_LT(high.step->rise_time_s * 1.3, low.step->rise_time_s);
}

// The position loop (--loop position): the drive stays in CSP and a
// square, then sines, of +-0.02 mm are added to its position command. The
// simulated drive's position loop is proportional (0x60FB:1, in 0.01/s)
// with full velocity feed-forward: the sines are followed by the
// feed-forward, a step (a one-cycle ramp of the target) by the
// proportional gain and a one-cycle pulse of feed-forward, so its 10-90 %
// rise is at most about that of a first-order loop, 2.2 / Kp. A lower
// velocity gain below it must show as a slower rise.
// A response of the velocity loop at the same gains stays in the state
// beside it; one at other gains is dropped.
TEST_F(ResponseE2e, ThePositionLoopIsMeasuredInCspItsStepRisesAsItsGainSays) {
  write_machine();
  const AxisResponse v = measure("");
  ASSERT_TRUE(v.skipped.empty() && v.step && v.chirp) << v.skipped;
  const AxisResponse p = measure("", "--loop position");
  ASSERT_TRUE(p.position_step && p.position_chirp);
  EXPECT_EQ(p.position_step->amplitude_mm_s, 0.02) << "the position loop's amplitude, in mm";
  EXPECT_EQ(e2e::read_text(p.position_chirp->csv).substr(0, e2e::read_text(p.position_chirp->csv).find('\n')),
            kPositionResponseCsvHeader);
  ASSERT_TRUE(p.step && p.chirp) << "the velocity loop's figures at the same gains stay";
  EXPECT_EQ(p.step->csv, v.step->csv);
  const uint32_t k = v.gains.velocity_gain;
  const AxisResponse low = measure(std::to_string(k / 10), "--loop position");
  const AxisResponse high = measure(std::to_string(k / 4), "--loop position");
  ASSERT_TRUE(low.position_step && low.position_chirp && high.position_step && high.position_chirp);
  EXPECT_FALSE(low.step) << "the velocity loop's figures were measured at other gains";
  for (const auto* r : {&low, &high, &p})
    std::printf("velocity gain %u, position loop: rise %.2f ms, overshoot %.1f %%, bandwidth %.1f Hz%s\n",
                r->gains.velocity_gain, r->position_step->rise_time_s * 1e3, r->position_step->overshoot_pct,
                r->position_chirp->bandwidth_hz, r->position_chirp->bandwidth_above ? " (above)" : "");
  ASSERT_TRUE(p.gains.position_gain) << "the simulated drive has 0x60FB:1";
  const double kp = *p.gains.position_gain * 0.01;  // 1/s
  // The feed-forward's one-cycle pulse moves the axis part of the step at
  // once (most of it with a fast velocity loop: rises of 1.5-14 ms were
  // seen at Kp 150/s), so the rise is at most about 2.2 / Kp.
  EXPECT_LT(p.position_step->rise_time_s, 1.25 * 2.2 / kp) << "Kp " << kp << "/s";
  EXPECT_LT(high.position_step->rise_time_s, low.position_step->rise_time_s);
  EXPECT_GT(p.position_chirp->points.size(), 5u);
}

// ... and puts back the velocity gain it found (a gain written with
// --velocity-gain is the response's, not the drive's).
TEST_F(ResponseE2e, CtrlCDuringTheSweepStopsWithTheMachineOffAndLeavesTheStateAlone) {
  write_machine();
  const std::string before = e2e::read_text(state_);
  const auto out = dir_ / "out.txt";
  // SIGINT once the sweep runs (the third test), as Ctrl-C does.
  const auto r = testing::run_shell(
      "'" + (bin_ / "cnc-commission").string() + "' --state '" + state_.string() + "' axis X response --bring-up '" +
      m_.string() + "' --velocity-gain 777 > '" + out.string() + "' 2>&1 & pid=$!; for i in $(seq 600); do grep -q '^progress: 3/' '" +
      out.string() + "' && break; sleep 0.1; done; kill -INT $pid; wait $pid; echo \"status $?\"");
  const std::string text = e2e::read_text(out);
  std::printf("%s%s", text.c_str(), r.text.c_str());
  EXPECT_NE(r.text.find("status 1"), std::string::npos) << r.text;
  EXPECT_NE(text.find("aborted"), std::string::npos) << text;
  EXPECT_NE(text.find("the machine is off again, the drives disabled"), std::string::npos) << text;
  EXPECT_NE(text.find("wrote 777 to 0x60F9:01"), std::string::npos) << text;
  EXPECT_NE(text.find("put back the velocity gain "), std::string::npos) << text;
  EXPECT_EQ(e2e::read_text(state_), before) << "an aborted response changed the state";
}

}  // namespace
}  // namespace cnc::commission
