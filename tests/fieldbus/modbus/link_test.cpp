#include <gtest/gtest.h>

#include <cmath>

#include "core/util/messages.hpp"
#include "fieldbus/modbus/link.hpp"
#include "tests/fieldbus/modbus/sim_fixture.hpp"

using namespace cnc;
using namespace cnc::modbus;
using namespace cnc::modbus::testing;
using modbus_sim::Family;

namespace {

struct Case {
  const char* profile;
  Family family;
  bool tcp;
};

std::string case_name(const ::testing::TestParamInfo<Case>& i) {
  return std::string(i.param.profile) + (i.param.tcp ? "_tcp" : "_rtu_pty");
}

struct Rig {
  explicit Rig(Family family, bool tcp, const std::string& profile = "", const std::string& extra = "")
      : server(std::make_unique<modbus_sim::Server>(sim_config(family, tcp))) {
    server->start();
    const std::string p = profile.empty() ? to_string(family) : profile;
    ini = ini::IniFile::parse(link_ini(*server, tcp, p, extra), "test.ini");
    link = std::make_unique<Link>(load_link_config(ini, "MODBUS", "modbus.0"), &messages);
    link->start();
  }
  VfdPort& vfd() { return *link->vfds()[0]; }
  void command(bool run, bool reverse, double rpm) {
    cmd.run = run;
    cmd.reverse = reverse;
    cmd.speed_rpm = rpm;
    vfd().command.write(cmd);
  }
  VfdFeedback feedback() { return vfd().feedback.read(); }
  // The next feedback read after now.
  VfdFeedback fresh() {
    const int64_t t = monotonic_ns();
    eventually([&] { return feedback().ok_ns > t; });
    return feedback();
  }
  bool message_contains(const std::string& text) {
    Message m;
    while (messages.pop(m)) seen += std::string(m.text.c_str()) + "\n";
    return seen.find(text) != std::string::npos;
  }

  std::unique_ptr<modbus_sim::Server> server;
  ini::IniFile ini;
  MessageQueue messages;
  std::unique_ptr<Link> link;
  VfdCommand cmd;
  std::string seen;
};

class VfdProfileOnSim : public ::testing::TestWithParam<Case> {};

}  // namespace

// Each profile drives the simulated drive of its family: forward to speed,
// reverse, stop; the feedback follows, and a trip reads back as its text.
TEST_P(VfdProfileOnSim, RunsReversesStopsAndReadsFaults) {
  const Case c = GetParam();
  Rig rig(c.family, c.tcp, c.profile);
  rig.command(true, false, 12000);  // 200 Hz at 60 rpm/Hz
  ASSERT_TRUE(eventually([&] { return std::fabs(rig.feedback().frequency_hz - 200) < 0.2; }))
      << "frequency " << rig.feedback().frequency_hz << "\n" << (rig.message_contains("?"), rig.seen);
  rig.server->with_device([](modbus_sim::Device& d) {
    EXPECT_TRUE(d.model().run());
    EXPECT_FALSE(d.model().reverse());
    EXPECT_NEAR(d.model().reference_hz(), 200, 0.1);
  });
  EXPECT_GT(rig.feedback().current_a, 0.0);
  EXPECT_FALSE(rig.feedback().reverse);

  rig.command(true, true, 6000);
  ASSERT_TRUE(eventually([&] {
    bool rev = false;
    rig.server->with_device([&](modbus_sim::Device& d) { rev = d.model().output_hz() < -99.8; });
    return rev && std::fabs(rig.feedback().frequency_hz - 100) < 0.2;
  }));
  EXPECT_TRUE(rig.feedback().reverse);

  rig.command(false, false, 6000);
  ASSERT_TRUE(eventually([&] { return rig.feedback().frequency_hz < 0.01; }));
  rig.server->with_device([](modbus_sim::Device& d) { EXPECT_FALSE(d.model().run()); });

  const VfdProfile& profile = rig.vfd().config.profile;
  if (profile.fault.present) {
    rig.command(true, false, 3000);
    rig.server->trip_overcurrent();
    const uint16_t code = modbus_sim::overcurrent_code(c.family);
    ASSERT_TRUE(eventually([&] { return rig.feedback().fault_code == code; }));
    EXPECT_EQ(profile.fault_text(code).rfind("fault code", 0), std::string::npos) << "the table names the trip";
    EXPECT_TRUE(eventually([&] { return rig.message_contains("drive fault " + std::to_string(code)); })) << rig.seen;
    EXPECT_EQ(std::string(rig.vfd().fault_text.read().c_str()), profile.fault_text(code));
    if (!profile.fault_reset.empty()) {
      ++rig.cmd.reset_count;
      rig.vfd().command.write(rig.cmd);
      EXPECT_TRUE(eventually([&] { return rig.feedback().fault_code == 0; }));
    }
  }
  // Timeouts are not asserted: a loaded host may delay the simulator.
  EXPECT_EQ(rig.vfd().counters.crc_errors.load(), 0u);
  EXPECT_EQ(rig.vfd().counters.exceptions.load(), 0u);
}

INSTANTIATE_TEST_SUITE_P(
    Families, VfdProfileOnSim,
    ::testing::Values(Case{"generic", Family::Delta, true}, Case{"generic", Family::Delta, false},
                      Case{"gs2", Family::Gs2, true}, Case{"gs2", Family::Gs2, false},
                      Case{"delta", Family::Delta, true}, Case{"delta", Family::Delta, false},
                      Case{"yaskawa", Family::Yaskawa, true}, Case{"yaskawa", Family::Yaskawa, false},
                      Case{"atv", Family::Atv, true}, Case{"atv", Family::Atv, false},
                      Case{"huanyang", Family::Huanyang, false}),
    case_name);

TEST(ModbusLink, SilentSlaveIsCountedReportedAndRecovered) {
  for (bool tcp : {true, false}) {
    SCOPED_TRACE(tcp ? "tcp" : "rtu");
    Rig rig(Family::Delta, tcp);
    rig.command(true, false, 6000);
    ASSERT_TRUE(eventually([&] { return rig.feedback().frequency_hz > 99; }));
    rig.server->set_silent(true);
    ASSERT_TRUE(eventually([&] { return rig.vfd().counters.timeouts.load() >= 3; }));
    const int64_t last_ok = rig.feedback().ok_ns;
    EXPECT_TRUE(eventually([&] { return rig.message_contains("no answer within 200 ms"); })) << rig.seen;
    EXPECT_NE(std::string(rig.vfd().fault_text.read().c_str()).find("no communication"), std::string::npos);
    EXPECT_EQ(rig.feedback().ok_ns, last_ok) << "no exchange succeeded meanwhile";
    rig.server->set_silent(false);
    EXPECT_TRUE(eventually([&] { return rig.feedback().ok_ns > last_ok; })) << "polling resumed after the back-off";
    EXPECT_TRUE(eventually([&] { return rig.message_contains("communication restored"); })) << rig.seen;
  }
}

TEST(ModbusLink, WrongCrcIsCountedAndTheNextAnswerIsTaken) {
  for (Family f : {Family::Delta, Family::Huanyang}) {
    SCOPED_TRACE(to_string(f));
    Rig rig(f, false);
    rig.command(true, false, 6000);
    ASSERT_TRUE(eventually([&] { return rig.feedback().frequency_hz > 99; }));
    rig.server->set_bad_crc(3);
    ASSERT_TRUE(eventually([&] { return rig.vfd().counters.crc_errors.load() >= 1; }));
    const int64_t t = monotonic_ns();
    EXPECT_TRUE(eventually([&] { return rig.feedback().ok_ns > t; }));
    EXPECT_TRUE(eventually([&] { return rig.message_contains("CRC"); })) << rig.seen;
  }
}

TEST(ModbusLink, ExceptionAnswersAreCountedWithTheirCode) {
  Rig rig(Family::Yaskawa, true);
  rig.command(true, false, 6000);
  ASSERT_TRUE(eventually([&] { return rig.feedback().ok_ns != 0; }));
  rig.server->set_exception(4, 2);  // slave device failure, twice
  ASSERT_TRUE(eventually([&] { return rig.vfd().counters.exceptions.load() >= 1; }));
  EXPECT_EQ(rig.vfd().counters.last_exception.load(), 4u);
  const int64_t t = monotonic_ns();
  EXPECT_TRUE(eventually([&] { return rig.feedback().ok_ns > t; }));
  EXPECT_TRUE(eventually([&] { return rig.message_contains("exception 4"); })) << rig.seen;
}

TEST(ModbusLink, ReconnectsAfterTheServerDropsOrRestarts) {
  Rig rig(Family::Atv, true);
  rig.command(true, false, 6000);
  ASSERT_TRUE(eventually([&] { return rig.link->counters().connects.load() == 1 && rig.feedback().ok_ns != 0; }));
  rig.server->drop_connection();
  ASSERT_TRUE(eventually([&] { return rig.link->counters().connects.load() >= 2; })) << rig.seen;
  const int64_t t = monotonic_ns();
  EXPECT_TRUE(eventually([&] { return rig.feedback().ok_ns > t; }));
  // A new server on the same port: the drive lost its state and gets the
  // whole command again.
  const int port = rig.server->port();
  rig.server->stop();
  auto cfg = sim_config(Family::Atv, true);
  cfg.port = port;
  rig.server = std::make_unique<modbus_sim::Server>(cfg);
  rig.server->start();
  EXPECT_TRUE(eventually([&] {
    bool running = false;
    rig.server->with_device([&](modbus_sim::Device& d) { running = d.model().output_hz() > 99; });
    return running;
  })) << rig.seen;
  EXPECT_TRUE(rig.message_contains("connected")) << rig.seen;
}

TEST(ModbusLink, StopDrivesTellsEveryVfdToStop) {
  Rig rig(Family::Gs2, false);
  rig.command(true, false, 6000);
  ASSERT_TRUE(eventually([&] { return rig.feedback().frequency_hz > 99; }));
  EXPECT_TRUE(rig.link->stop_drives(2'000'000'000));
  rig.server->with_device([](modbus_sim::Device& d) { EXPECT_FALSE(d.model().run()); });
}

TEST(ModbusLink, RemoteIoMapsCoilsInputsAndRegistersWithScaling) {
  auto cfg = sim_config(Family::Io, true);
  modbus_sim::Server server(cfg);
  server.start();
  server.with_device([](modbus_sim::Device& d) {
    d.discrete[2] = 1;
    d.input_regs[5] = static_cast<uint16_t>(-123);
  });
  const std::string text = "[MODBUS]\nTRANSPORT = TCP\nHOST = 127.0.0.1\nPORT = " + std::to_string(server.port()) +
                           "\nTIMEOUT_MS = 200\nIO = 1\n[MODBUS_IO_1]\nPOLL_MS = 5\nCOIL = 0 3\nDISCRETE_INPUT = 1 3 poll_ms=2\n"
                           "INPUT_REGISTER = 5 1 float signed scale=0.1 offset=1\nHOLDING_REGISTER = 7 1 s32 signed\n";
  const auto ini = ini::IniFile::parse(text, "io.ini");
  Link link(load_link_config(ini, "MODBUS", "modbus.0"), nullptr);
  link.start();
  IoPort& io = *link.ios()[0];
  IoOutputs out;
  out.value[1] = 1;    // coil 1
  out.value[7] = -42;  // holding register 7 (value index 3 + 3 + 1)
  io.outputs.write(out);
  ASSERT_TRUE(eventually([&] {
    const IoInputs in = io.inputs.read();
    return in.map_ns[2] != 0 && in.map_ns[1] != 0;
  }));
  const IoInputs in = io.inputs.read();
  EXPECT_EQ(in.value[3 + 1], 1.0) << "discrete input 2";
  EXPECT_EQ(in.value[3 + 0], 0.0) << "discrete input 1";
  EXPECT_NEAR(in.value[6], -123 * 0.1 + 1, 1e-9) << "input register 5, signed, scaled";
  EXPECT_TRUE(eventually([&] {
    bool ok = false;
    server.with_device([&](modbus_sim::Device& d) {
      ok = d.coils[1] == 1 && d.coils[0] == 0 && static_cast<int16_t>(d.holding_regs[7]) == -42;
    });
    return ok;
  }));
}
