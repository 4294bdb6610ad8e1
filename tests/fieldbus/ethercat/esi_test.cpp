// ESI XML files: parsing what the master uses, errors with file and line,
// and the master taking PDO defaults from the file.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "tests/fieldbus/ethercat/bus.hpp"
#ifdef CNC_ETHERCAT_ESI
#include "fieldbus/ethercat/esi.hpp"
#endif

namespace cnc::ethercat {
namespace {

using ::testing::HasSubstr;

#ifdef CNC_ETHERCAT_ESI
const std::string kEsi = (cnc::testing::source_dir() / "tests/fieldbus/ethercat/data/sim_drive.xml").string();

TEST(EthercatEsi, ReadsIdentityPdosAndAssignActivate) {
  const EsiFile f = load_esi(kEsi);
  EXPECT_EQ(f.vendor_id, 0x00000CC1u);
  EXPECT_EQ(f.vendor_name, "cnc project");
  ASSERT_EQ(f.devices.size(), 1u);
  const EsiDevice& d = f.devices[0];
  EXPECT_EQ(d.type, "SIM402");
  EXPECT_EQ(d.name, "Simulated CiA 402 servo drive");
  EXPECT_EQ(d.product_code, 0x402u);
  EXPECT_EQ(d.revision, 0x00010000u);
  ASSERT_EQ(d.rx_pdos.size(), 1u);  // the optional 0x1601 is not assigned
  EXPECT_EQ(d.rx_pdos[0].index, 0x1600);
  EXPECT_EQ(d.rx_pdos[0].sm, 2);
  ASSERT_EQ(d.rx_pdos[0].entries.size(), 3u);
  EXPECT_EQ(d.rx_pdos[0].entries[2].index, 0x60B8);
  EXPECT_EQ(d.rx_pdos[0].entries[2].bits, 16);
  EXPECT_EQ(d.rx_pdos[0].entries[1].data_type, 0x04);
  EXPECT_EQ(d.tx_pdos[0].entries[2].name, "Velocity actual value");
  EXPECT_TRUE(d.has_dc);
  EXPECT_EQ(d.assign_activate, 0x0300);  // the first operation mode
  EXPECT_EQ(f.find(0x402, 0x00020000), &f.devices[0]);  // another revision: the closest one
  EXPECT_EQ(f.find(0x403, 0), nullptr);
}

TEST(EthercatEsi, ErrorsNameFileAndLine) {
  try {
    parse_esi("<EtherCATInfo>\n<Vendor><Id>#xZZ</Id></Vendor>\n</EtherCATInfo>", "bad.xml");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("bad.xml:2: Vendor Id: \"#xZZ\" is not a number"));
  }
  try {
    parse_esi("<EtherCATInfo>\n<Vendor>\n</EtherCATInfo>", "broken.xml");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("broken.xml:3: mismatched tag"));
  }
  uint64_t v = 0;
  EXPECT_TRUE(parse_esi_number(" #x1A00 ", v));
  EXPECT_EQ(v, 0x1A00u);
  EXPECT_TRUE(parse_esi_number("42", v));
  EXPECT_FALSE(parse_esi_number("0x10", v));
}

TEST(EthercatEsi, MasterTakesPdoDefaultsFromTheFile) {
  MasterConfig cfg;
  SlaveConfig s;
  s.position = 2;
  s.esi = kEsi;
  cfg.slaves.push_back(s);
  test::Bus bus(2, cfg);
  EXPECT_TRUE(bus.master->output(2, 0x60B8, 0));
  EXPECT_TRUE(bus.master->input(2, 0x606C, 0));
  EXPECT_FALSE(bus.master->input(1, 0x606C, 0));  // slave 1: SII defaults
  EXPECT_THAT(bus.master->slaves()[1].esi_device, HasSubstr("SIM402"));
  ASSERT_TRUE(bus.reach_op());
  EXPECT_EQ(bus.master->counters().last_wkc.load(), 6);
}

TEST(EthercatEsi, FileForAnotherDeviceStopsStartUp) {
  testing::TempDir dir;
  std::string xml = "<EtherCATInfo><Vendor><Id>#x00000CC1</Id></Vendor><Descriptions><Devices><Device>"
                    "<Type ProductCode=\"#x999\" RevisionNo=\"1\">OTHER</Type></Device></Devices></Descriptions>"
                    "</EtherCATInfo>";
  MasterConfig cfg;
  SlaveConfig s;
  s.position = 1;
  s.esi = dir.write("other.xml", xml).string();
  cfg.slaves.push_back(s);
  test::Bus bus(1, cfg, false);
  try {
    bus.master->start_up();
    FAIL();
  } catch (const StartupError& e) {
    EXPECT_THAT(e.what(), HasSubstr("describes no device with product code 0x00000402"));
  }
}
#else
TEST(EthercatEsi, NotBuilt) { GTEST_SKIP() << "built without expat: ESI files are not read"; }
#endif

}  // namespace
}  // namespace cnc::ethercat
