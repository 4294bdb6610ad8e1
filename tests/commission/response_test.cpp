// Step 7's loop response: the analysis on a known second-order system
// (step figures and the -3 dB bandwidth from the closed forms), the
// state, and the response configuration's additions.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <functional>

#include "commission/response.hpp"
#include "commission/restore.hpp"
#include "commission/state.hpp"
#include "tests/commission/sim_bus_scan.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission {
namespace {

// y'' + 2 zeta wn y' + wn^2 y = wn^2 u, sampled every `dt` (integrated at
// dt / 50): the command `u(t)` and the response.
std::vector<ResponseSample> second_order(double wn, double zeta, double dt, double seconds,
                                         const std::function<double(double)>& u) {
  std::vector<ResponseSample> out;
  double y = 0, v = 0;
  const int sub = 50;
  const double h = dt / sub;
  for (double t = 0; t < seconds; t += dt) {
    out.push_back({t, u(t), y, 0});
    for (int k = 0; k < sub; ++k) {
      const double a = wn * wn * (u(t) - y) - 2 * zeta * wn * v;
      v += a * h;
      y += v * h;
    }
  }
  return out;
}

double overshoot_pct(double zeta) { return 100 * std::exp(-M_PI * zeta / std::sqrt(1 - zeta * zeta)); }
double bandwidth_of(double wn, double zeta) {
  const double z2 = zeta * zeta;
  return wn * std::sqrt(1 - 2 * z2 + std::sqrt(4 * z2 * z2 - 4 * z2 + 2)) / (2 * M_PI);
}

TEST(ResponseStep, ASecondOrderSystemsOvershootRiseAndSettlingAreItsClosedForms) {
  const double wn = 2 * M_PI * 20, zeta = 0.4;
  // A square wave +-2 mm/s, 0.2 s per level.
  const auto r = second_order(wn, zeta, 1e-3, 1.0, [](double t) { return std::fmod(t, 0.4) < 0.2 ? -2.0 : 2.0; });
  const StepResponse s = analyse_step(r);
  EXPECT_GE(s.edges, 3);
  EXPECT_NEAR(s.amplitude_mm_s, 2.0, 1e-9);
  EXPECT_NEAR(s.overshoot_pct, overshoot_pct(zeta), 1.5);  // 25.4 %
  // 10-90 % rise of zeta 0.4: 1.46 / wn (numerically), settling into 5 %
  // about 3 / (zeta wn) (the envelope).
  EXPECT_NEAR(s.rise_time_s, 1.46 / wn, 1.0e-3);
  EXPECT_GT(s.settling_time_s, 0.6 * 3 / (zeta * wn));
  EXPECT_LT(s.settling_time_s, 1.2 * 3 / (zeta * wn));
  // Better damped: less overshoot, none at zeta 1.
  const auto d = second_order(wn, 1.0, 1e-3, 1.0, [](double t) { return std::fmod(t, 0.4) < 0.2 ? -2.0 : 2.0; });
  EXPECT_LT(analyse_step(d).overshoot_pct, 0.5);
}

TEST(ResponseStep, ACommandWithoutAnEdgeOrAResponseThatNeverRisesIsRefused) {
  std::vector<ResponseSample> flat;
  for (int i = 0; i < 100; ++i) flat.push_back({i * 1e-3, 1.0, 1.0, 0});
  EXPECT_THROW(analyse_step(flat), std::invalid_argument);
  std::vector<ResponseSample> dead;
  for (int i = 0; i < 100; ++i) dead.push_back({i * 1e-3, i < 50 ? -1.0 : 1.0, -1.0, 0});
  EXPECT_THROW(analyse_step(dead), std::invalid_argument);
}

TEST(ResponseSine, GainPhaseAndTheMinus3dBBandwidthOfASecondOrderSystem) {
  const double wn = 2 * M_PI * 30, zeta = 0.5;
  std::vector<FrequencyPoint> points;
  for (double f : {2.0, 4.0, 8.0, 16.0, 24.0, 32.0, 48.0, 64.0, 100.0}) {
    const auto r = second_order(wn, zeta, 1e-3, 6 / f + 0.5, [f](double t) { return 2 * std::sin(2 * M_PI * f * t); });
    // The steady state only (the transient has died out after 0.5 s).
    std::vector<ResponseSample> tail(r.end() - static_cast<long>(std::ceil(4 / f / 1e-3)), r.end());
    const FrequencyPoint p = analyse_sine(tail, f);
    const double w = 2 * M_PI * f;
    const std::complex<double> h = wn * wn / std::complex<double>(wn * wn - w * w, 2 * zeta * wn * w);
    EXPECT_NEAR(p.gain_db, 20 * std::log10(std::abs(h)), 0.3) << f << " Hz";
    // The sampled output lags half a step of the integration: w dt / 2.
    EXPECT_NEAR(p.phase_deg, std::arg(h) * 180 / M_PI, 3 + f * 360 * 1e-3) << f << " Hz";
    points.push_back(p);
  }
  bool above = true;
  const double bw = bandwidth_hz(points, above);
  EXPECT_FALSE(above);
  EXPECT_NEAR(bw, bandwidth_of(wn, zeta), 0.08 * bandwidth_of(wn, zeta));  // 38 Hz
  // Phase unwrapped: falling through -180 without a jump.
  for (std::size_t i = 1; i < points.size(); ++i) EXPECT_LT(points[i].phase_deg, points[i - 1].phase_deg + 1);
  // Only the lowest points: the bandwidth lies above them.
  std::vector<FrequencyPoint> low(points.begin(), points.begin() + 3);
  EXPECT_DOUBLE_EQ(bandwidth_hz(low, above), 8.0);
  EXPECT_TRUE(above);
}

TEST(ResponseSine, LessThanOneCycleIsRefused) {
  std::vector<ResponseSample> r;
  for (int i = 0; i < 100; ++i) r.push_back({i * 1e-3, std::sin(i * 1e-3), 0, 0});
  EXPECT_THROW(analyse_sine(r, 2.0), std::invalid_argument);
}

TEST(ResponseState, IsKeptInTheStateFile) {
  testing::TempDir dir;
  State s;
  Axis a;
  a.letter = 'X';
  AxisResponse r;
  r.gains.velocity_gain = 3480;
  r.gains.velocity_integral = 60;
  r.gains.position_gain = 15000;
  r.step = StepResponse{2, 5, 0.004, 12.5, 0.02, "x-response-step.csv"};
  ChirpResponse c;
  c.points = {{2, 0.1, -5}, {20, -1, -60}, {80, -6, -150}};
  c.bandwidth_hz = 41.5;
  c.csv = "x-response-chirp.csv";
  r.chirp = c;
  a.response = r;
  s.axes.push_back(a);
  save_state(s, dir / "s.json");
  const State b = load_state(dir / "s.json");
  ASSERT_TRUE(b.axes[0].response);
  const AxisResponse& x = *b.axes[0].response;
  EXPECT_EQ(x.gains.velocity_gain, 3480u);
  EXPECT_EQ(x.gains.position_gain, 15000u);
  ASSERT_TRUE(x.step);
  EXPECT_DOUBLE_EQ(x.step->overshoot_pct, 12.5);
  EXPECT_EQ(x.step->csv, "x-response-step.csv");
  ASSERT_TRUE(x.chirp);
  ASSERT_EQ(x.chirp->points.size(), 3u);
  EXPECT_DOUBLE_EQ(x.chirp->points[2].gain_db, -6);
  EXPECT_DOUBLE_EQ(x.chirp->bandwidth_hz, 41.5);
  // Skipped: the reason kept.
  s.axes[0].response = AxisResponse{"node 1 has no velocity control parameter set 0x60F9", {}, {}, {}};
  save_state(s, dir / "s.json");
  EXPECT_EQ(load_state(dir / "s.json").axes[0].response->skipped, "node 1 has no velocity control parameter set 0x60F9");
}

// X and Y scaled and inside known limits, on CAN nodes 1 and 2 or on
// EtherCAT slaves 1 and 2.
State two_axes(bool ethercat) {
  State s;
  if (ethercat) s.ethercat_interface = "raw:ecm";
  else s.interface = "virtual:resp";
  Axis x;
  x.letter = 'X';
  x.joint = 0;
  x.scaling.encoder_counts = 131072;
  x.scaling.screw_lead = 5;
  x.min_limit = 0;
  x.max_limit = 100;
  x.limits_source = "entered";
  Axis y = x;
  y.letter = 'Y';
  y.joint = 1;
  (ethercat ? x.slave : x.node) = 1;
  (ethercat ? y.slave : y.node) = 2;
  s.axes = {x, y};
  return s;
}

// The response configuration's INI and HAL text for `letter`.
std::pair<std::string, std::string> response_files(const State& s, char letter, const std::filesystem::path& dir) {
  std::string ini, hal;
  for (const auto& f : response_configuration(s, letter, dir, "r")) {
    if (f.path.extension() == ".ini") ini = f.content;
    if (f.path.extension() == ".hal") hal = f.content;
  }
  return {ini, hal};
}

TEST(ResponseConfiguration, MapsTheTargetVelocityAndWiresTheSignalGeneratorToTheAxisDrive) {
  testing::TempDir dir;
  State s = two_axes(false);
  const auto [ini, hal] = response_files(s, 'Y', dir.path());
  const auto node2 = ini.find("[CANOPEN_NODE_2]");
  ASSERT_NE(node2, std::string::npos);
  EXPECT_NE(ini.find("RPDO2 = 0x60FF:0:s32", node2), std::string::npos);
  EXPECT_EQ(ini.find("RPDO2 = 0x60FF:0:s32"), ini.find("RPDO2 = 0x60FF:0:s32", node2)) << "only on the axis' node";
  EXPECT_NE(ini.find("INTERFACE = virtual:resp,share\n"), std::string::npos);
  EXPECT_NE(hal.find("net response-vel response-mux.out => cia402.0.drive.01.vel-cmd"), std::string::npos);
  EXPECT_NE(hal.find("addf response.update servo-thread"), std::string::npos);
  EXPECT_EQ(response_sdo_interface(s).rfind("unix:/dev/shm/cnc-", 0), 0u);
  EXPECT_NE(response_sdo_interface(s).find(".can-resp"), std::string::npos);
  s.interface = "socketcan:can0";
  EXPECT_EQ(response_sdo_interface(s), "socketcan:can0");
}

// On EtherCAT the target velocity joins the ESI's default RxPDO of the
// axis' slave (the writer gives it none: the ESI's default is in use).
TEST(ResponseConfiguration, MapsTheTargetVelocityInTheRxPdoOfTheAxisEthercatSlave) {
  testing::TempDir dir;
  State s = two_axes(true);
  const auto [ini, hal] = response_files(s, 'X', dir.path());
  const auto slave1 = ini.find("[ETHERCAT_SLAVE_1]"), slave2 = ini.find("[ETHERCAT_SLAVE_2]");
  ASSERT_NE(slave1, std::string::npos);
  ASSERT_NE(slave2, std::string::npos);
  const std::string line = "\nRXPDO = 0x6040:0:u16 0x607A:0:s32 0x60B8:0:u16 0x60FF:0:s32\n";
  const auto rx = ini.find(line);
  ASSERT_NE(rx, std::string::npos) << ini;
  EXPECT_GT(rx, slave1);
  EXPECT_LT(rx, slave2) << "in the axis' slave's section";
  EXPECT_EQ(ini.find(line, rx + 1), std::string::npos) << "only on the axis' slave";
  EXPECT_EQ(ini.find("RPDO2"), std::string::npos);
  EXPECT_NE(ini.find("INTERFACE = raw:ecm\n"), std::string::npos);
  EXPECT_NE(hal.find("net response-vel response-mux.out => cia402.0.drive.00.vel-cmd"), std::string::npos);
  EXPECT_TRUE(response_gains_before_controller(*s.axis('X')));
}

// The gains by SDO on a simulated drive: read, written and read back; a
// gain the drive refuses names the object; a drive without 0x60F9 is
// skipped with the reason.
TEST(ResponseGains, AreReadAndWrittenBySdoAndADriveWithoutThemIsSkipped) {
  e2e::SimulatedCanDrives d;
  d.add(1);
  auto& other = d.add(2);
  other.od().set_before_read({0x60F9, 1}, [](const canopen::OdEntry&) { return 0x06020000u; });
  d.start();
  std::string why;
  const auto one = canopen_channel(*d.client, 1, 1'000'000'000), two = canopen_channel(*d.client, 2, 1'000'000'000);
  const auto g = read_loop_gains(*one, "node 1", why);
  ASSERT_TRUE(g) << why;
  EXPECT_GT(g->velocity_gain, 0u);
  EXPECT_EQ(g->velocity_integral, 60);
  ASSERT_TRUE(g->position_gain);
  EXPECT_EQ(*g->position_gain, 15000u);
  write_velocity_gain(*one, "node 1", 777);
  EXPECT_EQ(read_loop_gains(*one, "node 1", why)->velocity_gain, 777u);
  try {
    write_velocity_gain(*one, "node 1", 0);
    FAIL() << "a zero gain was taken";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("0x60F9:01"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(read_loop_gains(*two, "node 2", why));
  EXPECT_NE(why.find("node 2 has no readable velocity control parameter set 0x60F9"), std::string::npos) << why;
  EXPECT_NE(why.find("06020000"), std::string::npos) << why;
}

}  // namespace
}  // namespace cnc::commission
