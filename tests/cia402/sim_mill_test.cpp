// The simulated mill of configs/sim (CiA 402 drives behind CANopen, motion,
// task and I/O) stepped in simulated time through the task's commands, as
// an operator gives them: the amplifier handshake (joint.N.amp-ready-in
// wired to each drive's `enabled`) makes "machine on" answer only once the
// drives follow, so homing sent at once starts against drives that do.
#include <gtest/gtest.h>

#include "cia402/components.hpp"
#include "fieldbus/canopen/components.hpp"
#include "tests/comp/sim_mill.hpp"
#include "tests/fieldbus/canopen/pace.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;

TEST(Cia402SimMill, MachineOnIsDoneWhenEveryDriveFollowsAndHomingMayStartAtOnce) {
  cnc::testing::TempDir work;
  cnc::testing::SimMill mill(cnc::testing::source_dir() / "configs/sim", work.path() / "sim", "sim.ini",
                             [](hal::ComponentRegistry& r) {
                               canopen::register_components(r);
                               cia402::register_components(r);
                             });
  mill.pace = canopen::test::acyclic_pacer(mill.hal());
  mill.step(100);
  ASSERT_EQ(mill.send(ipc::CommandType::TaskSetState, 2).first, ipc::CommandState::Done) << mill.errors();
  // X and Y on canopen.0 (cia402.0), Z on canopen.1 beside the spindle.
  const char* const axes[] = {"cia402.0.drive.00", "cia402.0.drive.01", "cia402.1.drive.01"};
  for (const char* drive : axes) {
    EXPECT_EQ(mill.hal().get_value(std::string(drive) + ".enabled"), "FALSE");
  }
  const double asked = mill.seconds();
  const auto on = mill.send(ipc::CommandType::TaskSetState, 4);
  ASSERT_EQ(on.first, ipc::CommandState::Done) << on.second << mill.errors();
  // Answered in the cycle the last drive began to follow, not before.
  EXPECT_GT(mill.seconds() - asked, 0.002);
  for (const char* drive : axes) {
    EXPECT_EQ(mill.hal().get_value(std::string(drive) + ".enabled"), "TRUE") << drive;
  }
  // No pause for the drives: homing (X, Y by their drives, Z by motion on
  // the drive's switch and index) right after "on".
  const std::string missed0 = mill.hal().get_value("canopen.0.pdo-missed");
  const std::string missed1 = mill.hal().get_value("canopen.1.pdo-missed");
  const auto home = mill.send(ipc::CommandType::JointHome, -1);
  EXPECT_EQ(home.first, ipc::CommandState::Done) << home.second;
  EXPECT_EQ(mill.errors(), "");
  // Not one TPDO late from power-on to the end of homing: the plan fits
  // the bus (CanopenConfig.TheSimulatedMillFitsItsBusesAtOneKilohertz) and
  // the simulated drives send by priority as the plan assumes. (With
  // TX_QUEUE = FIFO the drives' 100 ms event PDOs queued before a TPDO1
  // made it miss its SYNC every 100 ms, 0 to 33 times per run.)
  EXPECT_EQ(missed0, "0");
  EXPECT_EQ(missed1, "0");
  EXPECT_EQ(mill.hal().get_value("canopen.0.pdo-missed"), "0");
  EXPECT_EQ(mill.hal().get_value("canopen.1.pdo-missed"), "0");
}
