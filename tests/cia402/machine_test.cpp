// The whole chain in one HAL, as the controller builds it: motion (motmod),
// the CANopen master, the drive layer (cia402) and simulated drives
// (cia402_sim) stepped by the servo thread. A plant with too low a gain
// trips the drive's own following-error window, or the motion controller's
// FERROR, whichever is tighter, each with its message.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "core/daemon/controller.hpp"
#include "core/hal/commands.hpp"
#include "core/hal/component.hpp"
#include "core/ini/ini_file.hpp"
#include "core/motion/motion_component.hpp"
#include "core/util/messages.hpp"
#include "sim/register.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;

namespace {

std::string machine_ini(const std::string& bus, double drive_window_mm, double ferror_mm) {
  return "[EMCMOT]\nSERVO_PERIOD = 1000000\n"
         "[KINS]\nKINEMATICS = trivkins coordinates=X\nJOINTS = 1\n"
         "[TRAJ]\nCOORDINATES = X\nLINEAR_UNITS = mm\nMAX_LINEAR_VELOCITY = 100\nMAX_LINEAR_ACCELERATION = 1000\n"
         "[AXIS_X]\nMIN_LIMIT = -1000\nMAX_LIMIT = 1000\nMAX_VELOCITY = 100\nMAX_ACCELERATION = 1000\n"
         "[JOINT_0]\nTYPE = LINEAR\nMIN_LIMIT = -1000\nMAX_LIMIT = 1000\nMAX_VELOCITY = 100\n"
         "MAX_ACCELERATION = 1000\nFERROR = " +
         std::to_string(ferror_mm) + "\nMIN_FERROR = " + std::to_string(ferror_mm) +
         "\n"
         "[CANOPEN]\nINTERFACE = virtual:" +
         bus +
         "\nNODE = 1\nMASTER_HEARTBEAT_MS = 100\nPDO_MISS_LIMIT = 0\n"
         "[CANOPEN_NODE_1]\nNAME = x-axis\nHEARTBEAT_MS = 100\nHEARTBEAT_TIMEOUT_MS = 5000\n"
         "RPDO1 = 0x6040:0:u16 0x607A:0:s32\nTPDO1 = 0x6041:0:u16 0x6064:0:s32\n"
         "TPDO2 = 0x6061:0:s8 0x603F:0:u16\nTPDO2_TRANSMISSION = 255\nTPDO2_INHIBIT_100US = 10\nTPDO2_EVENT_MS = 100\n"
         "[CIA402]\nBUS = canopen.0\nDRIVE = 0\n"
         "[CIA402_DRIVE_0]\nADDRESS = 1\nNAME = x-axis\nJOINT = 0\nENCODER_COUNTS = 10000\nSCREW_LEAD = 5\n"
         "FERROR_WINDOW = " +
         std::to_string(drive_window_mm) +
         "\nFERROR_TIMEOUT_MS = 5\nPROBE = NO\n"
         "[CIA402_SIM]\nINTERFACE = virtual:" +
         bus +
         "\nCLOCK = SERVO\nNODE = 1\n"
         "[CIA402_SIM_NODE_1]\nNAME = x-axis\nENCODER_COUNTS = 10000\nSCREW_LEAD = 5\n"
         "POSITION_GAIN = 2\nVELOCITY_FF = 0\nTORQUE_FF = 0\n";
}

const char* kHal =
    "loadrt [KINS]KINEMATICS\n"
    "loadrt motmod servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS\n"
    "loadrt cia402_sim\n"
    "loadrt canopen\n"
    "loadrt cia402\n"
    "addf canopen.0.read servo-thread\n"
    "addf cia402.0.read servo-thread\n"
    "addf motion-command-handler servo-thread\n"
    "addf motion-controller servo-thread\n"
    "addf cia402.0.write servo-thread\n"
    "addf canopen.0.write servo-thread\n"
    "addf cia402-sim.0.update servo-thread\n"
    "net pos-cmd joint.0.motor-pos-cmd => cia402.0.drive.00.pos-cmd\n"
    "net pos-fb cia402.0.drive.00.pos-fb => joint.0.motor-pos-fb\n"
    "net enable joint.0.amp-enable-out => cia402.0.drive.00.enable\n"
    "net fault cia402.0.drive.00.amp-fault => joint.0.amp-fault-in\n"
    "net ready cia402.0.drive.00.enabled => joint.0.amp-ready-in\n";

struct Machine {
  Machine(double drive_window_mm, double ferror_mm)
      : ini(ini::IniFile::parse(machine_ini(cnc::testing::unique_name("ferror"), drive_window_mm, ferror_mm), "m.ini")) {
    daemon::register_all_components(registry);
    sim::register_components(registry);
    hal::CommandInterpreter halcmd(hal, registry, &ini, &messages);
    halcmd.run_text(kHal, "m.hal");
    for (hal::Component* c : hal.components()) c->on_ready();
    motion = hal.find<motion::MotionComponent>("motmod");
    hal.start_threads();
  }
  ~Machine() {
    for (hal::Component* c : hal.components()) c->on_shutdown();
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    hal.stop_threads();
    hal.clear();
  }
  void command(motion::Cmd type, int joint = 0, double v0 = 0) {
    motion::MotionCommand c;
    c.type = type;
    c.joint = static_cast<int16_t>(joint);
    c.value[0] = v0;
    motion->submit(c);
  }
  bool wait_for_message(const std::string& part, int timeout_ms) {
    for (int i = 0; i < timeout_ms / 10; ++i) {
      Message m;
      while (messages.pop(m)) log += std::string(to_string(m.kind)) + " [" + m.source.c_str() + "] " + m.text.c_str() + "\n";
      if (log.find(part) != std::string::npos) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return false;
  }
  bool wait_enabled(int timeout_ms) {
    for (int i = 0; i < timeout_ms / 10; ++i) {
      if (hal.get_value("cia402.0.drive.00.enabled") == "TRUE") return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return false;
  }

  ini::IniFile ini;
  hal::Hal hal;
  hal::ComponentRegistry registry;
  MessageQueue messages;
  motion::MotionComponent* motion = nullptr;
  std::string log;
};

}  // namespace

TEST(Cia402Machine, ASoftLoopTripsMotionsFerrorWhenItIsTheTighterLimit) {
  ::setenv("CNC_NO_REALTIME", "1", 1);
  Machine m(/*drive window*/ 100.0, /*FERROR*/ 0.5);
  m.command(motion::Cmd::Enable);
  ASSERT_TRUE(m.wait_enabled(3000)) << m.log;
  m.command(motion::Cmd::JogCont, 0, 20.0);  // 20 mm/s: 10 mm of lag at a position gain of 2/s
  EXPECT_TRUE(m.wait_for_message("joint 0 following error", 5000)) << m.log;
  EXPECT_NE(m.log.find("exceeds its limit 0.5000"), std::string::npos) << m.log;
  EXPECT_EQ(m.log.find("0x8611"), std::string::npos) << m.log;  // the drive's window is wide: it did not trip
}

TEST(Cia402Machine, ASoftLoopTripsTheDrivesWindowWhenItIsTheTighterLimit) {
  ::setenv("CNC_NO_REALTIME", "1", 1);
  Machine m(/*drive window*/ 0.2, /*FERROR*/ 50.0);
  m.command(motion::Cmd::Enable);
  ASSERT_TRUE(m.wait_enabled(3000)) << m.log;
  m.command(motion::Cmd::JogCont, 0, 20.0);
  EXPECT_TRUE(m.wait_for_message("joint 0 amplifier fault", 5000)) << m.log;
  EXPECT_NE(m.log.find("x-axis: fault 0x8611 following error: the drive's following error window (0x6065/0x6066) was "
                       "exceeded"),
            std::string::npos)
      << m.log;
  EXPECT_NE(m.log.find("EMCY 0x8611"), std::string::npos) << m.log;
  EXPECT_EQ(m.log.find("exceeds its limit"), std::string::npos) << m.log;  // motion's FERROR did not trip
}
