// CoE SDO through the master's mailbox client and the simulated drive's
// server: expedited, normal and segmented transfers both ways, and aborts
// decoded with their CiA 301 meaning.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>

#include "fieldbus/canopen/sdo_abort.hpp"
#include "tests/fieldbus/ethercat/bus.hpp"

namespace cnc::ethercat {
namespace {

using ::testing::HasSubstr;

TEST(EthercatCoe, ExpeditedUploadAndDownload) {
  test::Bus bus(2);
  const SdoResult id = bus.master->sdo_upload(2, 0x1018, 1);
  ASSERT_TRUE(id.ok) << id.error;
  EXPECT_EQ(id.data, (std::vector<uint8_t>{0xC1, 0x0C, 0, 0}));
  const SdoResult w = bus.master->sdo_download(2, 0x6065, 0, {0x10, 0x27, 0, 0});
  ASSERT_TRUE(w.ok) << w.error;
  EXPECT_EQ(bus.segment->drive(1)->od().get<uint32_t>({0x6065, 0}), 10000u);
  const SdoResult r = bus.master->sdo_upload(2, 0x6065, 0);
  EXPECT_EQ(r.data, (std::vector<uint8_t>{0x10, 0x27, 0, 0}));
}

// The simulated drive's loop gains (0x60F9, 0x60FB: sim/cia402/drive_model)
// over CoE: the same dictionary as on CANopen, a refused gain decoded.
TEST(EthercatCoe, TheDrivesLoopGainsAreReadAndWrittenOverCoe) {
  test::Bus bus(1);
  const SdoResult r = bus.master->sdo_upload(1, 0x60F9, 1);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.data.size(), 4u);
  EXPECT_EQ(bus.master->sdo_upload(1, 0x60FB, 1).data, (std::vector<uint8_t>{0x98, 0x3A, 0, 0}));  // 150 1/s
  ASSERT_TRUE(bus.master->sdo_download(1, 0x60F9, 1, {0xE8, 0x03, 0, 0}).ok);
  EXPECT_EQ(bus.segment->drive(0)->od().get<uint32_t>({0x60F9, 1}), 1000u);
  EXPECT_EQ(bus.master->sdo_download(1, 0x60F9, 1, {0, 0, 0, 0}).abort_code, 0x06090030u);
}

TEST(EthercatCoe, NormalUploadOfAString) {
  test::Bus bus(1);
  const SdoResult r = bus.master->sdo_upload(1, 0x1008, 0);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(std::string(r.data.begin(), r.data.end()), "drive-1");
}

TEST(EthercatCoe, SegmentedTransfersBothWays) {
  test::Bus bus(1);
  std::vector<uint8_t> init(300, 0);
  bus.segment->drive(0)->od().add_bytes({0x2100, 0}, canopen::DataType::Domain, canopen::Access::ReadWrite, init, 300,
                                        "test domain");
  std::vector<uint8_t> data(300);
  std::iota(data.begin(), data.end(), uint8_t{7});
  const uint64_t before = bus.segment->drive(0)->sdo_requests();
  const SdoResult w = bus.master->sdo_download(1, 0x2100, 0, data);
  ASSERT_TRUE(w.ok) << w.error;
  // 112 bytes in the initiate request, then segments of up to 119 bytes.
  EXPECT_EQ(bus.segment->drive(0)->sdo_requests() - before, 3u);
  const SdoResult r = bus.master->sdo_upload(1, 0x2100, 0);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.data, data);
  // A length that leaves a short last segment (n bits in the command byte).
  std::vector<uint8_t> odd(115, 0x3C);
  ASSERT_TRUE(bus.master->sdo_download(1, 0x2100, 0, odd).ok);
  EXPECT_EQ(bus.master->sdo_upload(1, 0x2100, 0).data, odd);
}

TEST(EthercatCoe, AbortsAreDecoded) {
  test::Bus bus(1);
  SdoResult r = bus.master->sdo_upload(1, 0x6FFF, 0);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.abort_code, 0x06020000u);
  EXPECT_THAT(r.error, HasSubstr("aborted by the slave: 0x06020000"));
  EXPECT_THAT(r.error, HasSubstr(canopen::sdo_abort_text(0x06020000)));
  r = bus.master->sdo_download(1, 0x6041, 0, {1, 0});
  EXPECT_EQ(r.abort_code, 0x06010002u);  // read-only
  // The mapping cannot change outside PREOP.
  r = bus.master->sdo_download(1, 0x1600, 0, {0});
  EXPECT_EQ(r.abort_code, 0x08000022u);
  bus.segment->drive(0)->abort_sdo(0x6060, 0x06090030);
  r = bus.master->sdo_download(1, 0x6060, 0, {8});
  EXPECT_EQ(r.abort_code, 0x06090030u);
  bus.segment->drive(0)->abort_sdo(0, 0);
  EXPECT_TRUE(bus.master->sdo_download(1, 0x6060, 0, {8}).ok);
}

// IEC 61158-6-12 sends "Abort SDO Transfer" as CoE service 2 (SDO
// request); replies are service 3. Masters other than ours may accept
// nothing else.
TEST(EthercatCoe, TheSimulatedDriveSendsAbortsAsCoeService2) {
  test::Bus bus(1);
  ASSERT_TRUE(bus.master->sdo_upload(1, 0x1018, 1).ok);
  EXPECT_EQ(bus.segment->drive(0)->last_reply_service(), CoeService::SdoResponse);
  EXPECT_EQ(bus.master->sdo_upload(1, 0x6FFF, 0).abort_code, 0x06020000u);
  EXPECT_EQ(bus.segment->drive(0)->last_reply_service(), CoeService::SdoRequest);
}

TEST(EthercatCoe, CompleteAccessBothWays) {
  test::Bus bus(1, {}, false);
  bus.master->to_preop();  // mapping objects are writable in PREOP only
  SdoResult r = bus.master->sdo_upload(1, 0x1A00, 0, true);
  ASSERT_TRUE(r.ok) << r.error;
  // Sub-index 0 as 16 bits, then the four default entries.
  EXPECT_EQ(r.data, (std::vector<uint8_t>{4, 0, 0x10, 0, 0x41, 0x60, 0x20, 0, 0x64, 0x60, 0x08, 0, 0x61, 0x60,
                                          0x10, 0, 0x3F, 0x60}));
  r = bus.master->sdo_upload(1, 0x1018, 1, true);  // from sub-index 1: no count
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.data.size(), 16u);
  const std::vector<uint8_t> map{2, 0, 0x10, 0, 0x40, 0x60, 0x20, 0, 0x7A, 0x60};
  r = bus.master->sdo_download(1, 0x1600, 0, map, true);
  ASSERT_TRUE(r.ok) << r.error;
  canopen::ObjectDictionary& od = bus.segment->drive(0)->od();
  EXPECT_EQ(od.get<uint8_t>({0x1600, 0}), 2);
  EXPECT_EQ(od.get<uint32_t>({0x1600, 2}), 0x607A0020u);
  EXPECT_EQ(bus.master->sdo_upload(1, 0x1600, 0, true).data, map);
  // Entries are checked one by one: a non-mappable object aborts the whole transfer.
  r = bus.master->sdo_download(1, 0x1600, 0, {1, 0, 0x20, 0x01, 0x18, 0x10}, true);
  EXPECT_EQ(r.abort_code, 0x06040041u);
  EXPECT_EQ(bus.master->sdo_upload(1, 0x1018, 2, true).abort_code, 0x06010000u);  // only from 0 or 1
}

TEST(EthercatCoe, SdoInformationListsAndDescribesObjects) {
  test::Bus bus(1);
  std::string error;
  const std::vector<uint16_t> list = bus.master->sdo_info_list(1, error);
  ASSERT_TRUE(error.empty()) << error;
  EXPECT_GT(list.size(), 58u);  // more than one fragment of 58 indexes
  EXPECT_NE(std::find(list.begin(), list.end(), 0x6040), list.end());
  EXPECT_NE(std::find(list.begin(), list.end(), 0x1C12), list.end());
  EXPECT_TRUE(std::is_sorted(list.begin(), list.end()));
  const auto o = bus.master->sdo_info_object(1, 0x1018, error);
  ASSERT_TRUE(o) << error;
  EXPECT_EQ(o->name, "Identity");
  EXPECT_EQ(o->max_sub, 4);
  EXPECT_EQ(o->object_code, 9);
  const auto e = bus.master->sdo_info_entry(1, 0x6040, 0, error);
  ASSERT_TRUE(e) << error;
  EXPECT_EQ(e->name, "Controlword");
  EXPECT_EQ(e->data_type, 0x0006);
  EXPECT_EQ(e->bit_length, 16);
  EXPECT_EQ(e->access & 0x40, 0x40);  // RxPDO-mappable
  EXPECT_FALSE(bus.master->sdo_info_object(1, 0x5FFF, error));
  EXPECT_THAT(error, HasSubstr("0x06020000"));
}

TEST(EthercatCoe, MailboxWorksWhileTheCycleRuns) {
  test::Bus bus(3);
  ASSERT_TRUE(bus.reach_op());
  std::atomic<bool> done{false};
  SdoResult r;
  std::thread t([&] {
    r = bus.master->sdo_upload(3, 0x1018, 4);  // through the worker thread
    done = true;
  });
  bus.run_until([&] { return done.load(); }, 5000);
  t.join();
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.data[0], 3);  // serial of the third drive
  // Realtime requests: handle now, result a few cycles later.
  const int h = bus.master->rt_sdo_read(2, 0x6061, 0);
  ASSERT_GE(h, 0);
  uint32_t abort = 1, value = 0;
  EXPECT_TRUE(bus.run_until([&] { return bus.master->rt_sdo_poll(h, abort, value); }, 5000));
  EXPECT_EQ(abort, 0u);
  EXPECT_FALSE(bus.master->has_fault());
}

}  // namespace
}  // namespace cnc::ethercat
