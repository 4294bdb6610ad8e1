#include <gtest/gtest.h>

#include <map>
#include <numeric>
#include <optional>

#include "fieldbus/canopen/crc16.hpp"
#include "fieldbus/canopen/sdo_abort.hpp"
#include "fieldbus/canopen/sdo_client.hpp"
#include "fieldbus/canopen/slave_node.hpp"
#include "tests/fieldbus/canopen/sim.hpp"

using namespace cnc;
using namespace cnc::canopen;
using cnc::canopen::test::bytes_of;
using cnc::canopen::test::Sim;

namespace {

constexpr uint8_t kNode = 5;

std::vector<uint8_t> pattern(std::size_t n, uint8_t seed = 1) {
  std::vector<uint8_t> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i] = static_cast<uint8_t>(seed + i * 7);
  return v;
}

class SdoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    using D = DataType;
    using A = Access;
    od.add({0x2000, 0}, D::Unsigned8, A::ReadWrite, 0);
    od.add({0x2001, 0}, D::Unsigned16, A::ReadWrite, 100);
    od.set_limits({0x2001, 0}, 10, 1000);
    od.add({0x2002, 0}, D::Integer32, A::ReadWrite, 0);
    od.add({0x2003, 0}, D::Unsigned32, A::ReadOnly, 0xDEADBEEF);
    od.add({0x2004, 0}, D::Unsigned32, A::WriteOnly, 0);
    od.add_bytes({0x2005, 0}, D::Domain, A::ReadWrite, {}, 2000);
    od.add_string({0x2006, 0}, A::ReadWrite, "hello", 64);
    od.add({0x2007, 0}, D::Unsigned8, A::ReadOnly, 2);
    od.add({0x2007, 1}, D::Unsigned16, A::ReadWrite, 0);
    od.add({0x2007, 2}, D::Unsigned32, A::ReadWrite, 0);
    od.add({0x2008, 0}, D::Unsigned64, A::ReadWrite, 0);
    od.add({0x2009, 0}, D::Unsigned32, A::ReadWrite, 0);
    od.set_write_check({0x2009, 0}, [](const OdEntry&, const uint8_t*, std::size_t) -> uint32_t {
      return abort_code::kDeviceState;
    });
    node_port = sim.port("node");
    master_port = sim.port("master");
    SlaveOptions o;
    o.node_id = kNode;
    o.identity.device_name = "sdo test device";
    node = std::make_unique<SlaveNode>(od, *node_port, o);
    node->start(0);
    client = std::make_unique<SdoClient>(*master_port, kNode);
    sim.actors.push_back([this](int64_t now) { node->process(now); });
    sim.actors.push_back([this](int64_t now) {
      can::Frame f;
      while (master_port->receive(f)) client->on_frame(f, now);
      client->poll(now);
    });
    sim.run_for(1'000'000);
    sim.log.clear();
  }

  SdoResult upload(ObjectAddress a, SdoMode mode = SdoMode::Auto) {
    std::optional<SdoResult> r;
    client->upload(a, [&](const SdoResult& x) { r = x; }, mode);
    EXPECT_TRUE(sim.run_until([&] { return r.has_value(); }, 5'000'000'000));
    sim.run_for(1'000'000);  // the client's last frame reaches the server
    return r.value_or(SdoResult{});
  }
  SdoResult download(ObjectAddress a, std::vector<uint8_t> data, SdoMode mode = SdoMode::Auto) {
    std::optional<SdoResult> r;
    client->download(a, std::move(data), [&](const SdoResult& x) { r = x; }, mode);
    EXPECT_TRUE(sim.run_until([&] { return r.has_value(); }, 5'000'000'000));
    return r.value_or(SdoResult{});
  }
  std::vector<can::Frame> requests() const { return sim.frames_with_id(0x600 + kNode); }
  std::vector<can::Frame> responses() const { return sim.frames_with_id(0x580 + kNode); }

  Sim sim;
  ObjectDictionary od;
  std::unique_ptr<can::VirtualPort> node_port, master_port;
  std::unique_ptr<SlaveNode> node;
  std::unique_ptr<SdoClient> client;
};

}  // namespace

TEST_F(SdoTest, ExpeditedDownloadUsesTheSizedCommandBytes) {
  EXPECT_TRUE(download({0x2000, 0}, {0x42}).ok());
  EXPECT_TRUE(download({0x2001, 0}, {0x34, 0x02}).ok());
  EXPECT_TRUE(download({0x2002, 0}, {0xFE, 0xFF, 0xFF, 0xFF}).ok());
  EXPECT_EQ(od.get<uint8_t>({0x2000, 0}), 0x42);
  EXPECT_EQ(od.get<uint16_t>({0x2001, 0}), 0x234);
  EXPECT_EQ(od.get<int32_t>({0x2002, 0}), -2);
  const auto req = requests();
  ASSERT_EQ(req.size(), 3u);
  EXPECT_EQ(bytes_of(req[0]), (std::vector<uint8_t>{0x2F, 0x00, 0x20, 0x00, 0x42, 0, 0, 0}));
  EXPECT_EQ(req[1].data[0], 0x2B);
  EXPECT_EQ(req[2].data[0], 0x23);
  for (const auto& r : responses()) {
    EXPECT_EQ(r.len, 8) << "SDO frames always carry 8 bytes";
    EXPECT_EQ(r.data[0], 0x60);
  }
}

TEST_F(SdoTest, ExpeditedUploadAnswersWithTheSize) {
  od.set<uint8_t>({0x2000, 0}, 7);
  EXPECT_EQ(upload({0x2000, 0}).data, (std::vector<uint8_t>{7}));
  EXPECT_EQ(upload({0x2001, 0}).as<uint16_t>(), 100);
  const SdoResult r = upload({0x2003, 0});
  EXPECT_TRUE(r.ok());
  EXPECT_EQ(r.as<uint32_t>(), 0xDEADBEEFu);
  const auto resp = responses();
  ASSERT_EQ(resp.size(), 3u);
  EXPECT_EQ(resp[0].data[0], 0x4F);
  EXPECT_EQ(resp[1].data[0], 0x4B);
  EXPECT_EQ(bytes_of(resp[2]), (std::vector<uint8_t>{0x43, 0x03, 0x20, 0x00, 0xEF, 0xBE, 0xAD, 0xDE}));
  EXPECT_EQ(bytes_of(requests()[0]), (std::vector<uint8_t>{0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0}));
}

TEST_F(SdoTest, SegmentedDownloadTogglesAndMarksTheLastSegment) {
  const auto data = pattern(20);
  const SdoResult r = download({0x2005, 0}, data, SdoMode::Segmented);
  ASSERT_TRUE(r.ok()) << r.message();
  const OdEntry* e = od.find({0x2005, 0});
  ASSERT_EQ(e->size, 20u);
  EXPECT_TRUE(std::equal(data.begin(), data.end(), od.data(*e)));
  const auto req = requests();
  ASSERT_EQ(req.size(), 4u);
  EXPECT_EQ(bytes_of(req[0]), (std::vector<uint8_t>{0x21, 0x05, 0x20, 0x00, 20, 0, 0, 0}));
  EXPECT_EQ(req[1].data[0], 0x00) << "t=0, 7 bytes, not last";
  EXPECT_EQ(req[2].data[0], 0x10) << "t=1";
  EXPECT_EQ(req[3].data[0], 0x00 | (1 << 1) | 1) << "t=0, n=1 unused byte (6 bytes), c=1";
  const auto resp = responses();
  ASSERT_EQ(resp.size(), 4u);
  EXPECT_EQ(resp[1].data[0], 0x20);
  EXPECT_EQ(resp[2].data[0], 0x30);
  EXPECT_EQ(resp[3].data[0], 0x20);
}

TEST_F(SdoTest, SegmentedUploadOfAString) {
  const SdoResult r = upload({0x1008, 0});
  ASSERT_TRUE(r.ok()) << r.message();
  EXPECT_EQ(std::string(r.data.begin(), r.data.end()), "sdo test device");
  const auto resp = responses();
  ASSERT_EQ(resp.size(), 4u);
  EXPECT_EQ(bytes_of(resp[0]), (std::vector<uint8_t>{0x41, 0x08, 0x10, 0x00, 15, 0, 0, 0}));
  EXPECT_EQ(resp[1].data[0], 0x00);
  EXPECT_EQ(resp[2].data[0], 0x10);
  EXPECT_EQ(resp[3].data[0], 0x00 | (6 << 1) | 1) << "1 byte left: n=6, c=1";
  const auto req = requests();
  ASSERT_EQ(req.size(), 4u);
  EXPECT_EQ(req[1].data[0], 0x60);
  EXPECT_EQ(req[2].data[0], 0x70);
  EXPECT_EQ(req[3].data[0], 0x60);
}

TEST_F(SdoTest, EightByteValuesGoSegmentedBothWays) {
  const std::vector<uint8_t> v = {1, 2, 3, 4, 5, 6, 7, 8};
  ASSERT_TRUE(download({0x2008, 0}, v).ok());
  EXPECT_EQ(od.get<uint64_t>({0x2008, 0}), 0x0807060504030201ull);
  EXPECT_EQ(upload({0x2008, 0}).data, v);
}

TEST_F(SdoTest, BlockDownloadWithCrc) {
  const auto data = pattern(1000, 3);
  const SdoResult r = download({0x2005, 0}, data, SdoMode::Block);
  ASSERT_TRUE(r.ok()) << r.message();
  const OdEntry* e = od.find({0x2005, 0});
  ASSERT_EQ(e->size, 1000u);
  EXPECT_TRUE(std::equal(data.begin(), data.end(), od.data(*e)));
  const auto req = requests();
  EXPECT_EQ(bytes_of(req.front()), (std::vector<uint8_t>{0xC6, 0x05, 0x20, 0x00, 0xE8, 0x03, 0, 0}));
  // 1000 bytes = 143 segments: one sub-block of 127, one of 16.
  EXPECT_EQ(req.size(), 1u + 143u + 1u);
  EXPECT_EQ(req[127].data[0], 127);
  EXPECT_EQ(req[128].data[0], 1);
  EXPECT_EQ(req[143].data[0], 0x80 | 16) << "c=1 on the last segment";
  const uint16_t crc = crc16_ccitt(0, data.data(), data.size());
  const int unused = 7 - (1000 - 142 * 7);
  EXPECT_EQ(bytes_of(req.back()),
            (std::vector<uint8_t>{static_cast<uint8_t>(0xC1 | (unused << 2)), static_cast<uint8_t>(crc),
                                  static_cast<uint8_t>(crc >> 8), 0, 0, 0, 0, 0}));
  const auto resp = responses();
  ASSERT_EQ(resp.size(), 4u);
  EXPECT_EQ(resp[0].data[0], 0xA4);
  EXPECT_EQ(resp[0].data[4], 127);
  EXPECT_EQ(bytes_of(resp[1]), (std::vector<uint8_t>{0xA2, 127, 127, 0, 0, 0, 0, 0}));
  EXPECT_EQ(resp[2].data[1], 16);
  EXPECT_EQ(resp[3].data[0], 0xA1);
}

TEST_F(SdoTest, BlockUploadInSeveralSubBlocks) {
  const auto data = pattern(300, 9);
  od.write({0x2005, 0}, data.data(), data.size(), false);
  client->options().block_size = 10;
  const SdoResult r = upload({0x2005, 0}, SdoMode::Block);
  ASSERT_TRUE(r.ok()) << r.message();
  EXPECT_EQ(r.data, data);
  const auto req = requests();
  EXPECT_EQ(bytes_of(req[0]), (std::vector<uint8_t>{0xA4, 0x05, 0x20, 0x00, 10, 0, 0, 0}));
  EXPECT_EQ(req[1].data[0], 0xA3);
  EXPECT_EQ(bytes_of(req[2]), (std::vector<uint8_t>{0xA2, 10, 10, 0, 0, 0, 0, 0}));
  EXPECT_EQ(req.back().data[0], 0xA1);
  const auto resp = responses();
  EXPECT_EQ(bytes_of(resp[0]), (std::vector<uint8_t>{0xC6, 0x05, 0x20, 0x00, 0x2C, 0x01, 0, 0}));
  const uint16_t crc = crc16_ccitt(0, data.data(), data.size());
  EXPECT_EQ(resp.back().data[1], static_cast<uint8_t>(crc));
  EXPECT_EQ(resp.back().data[2], static_cast<uint8_t>(crc >> 8));
  EXPECT_EQ(resp.back().data[0], 0xC1 | ((7 - (300 - 42 * 7)) << 2));
}

TEST_F(SdoTest, BlockUploadSwitchesToNormalUploadBelowTheThreshold) {
  client->options().protocol_switch_threshold = 20;
  const SdoResult r = upload({0x1008, 0}, SdoMode::Block);
  ASSERT_TRUE(r.ok()) << r.message();
  EXPECT_EQ(std::string(r.data.begin(), r.data.end()), "sdo test device");
  EXPECT_EQ(responses()[0].data[0], 0x41) << "a segmented upload answers the block request";
}

TEST_F(SdoTest, LostBlockSegmentsAreRepeatedAfterTheAcknowledgement) {
  const auto data = pattern(700, 5);
  std::optional<SdoResult> r;
  client->download({0x2005, 0}, data, [&](const SdoResult& x) { r = x; }, SdoMode::Block);
  ASSERT_TRUE(sim.run_until([&] { return !responses().empty(); }));
  sim.bus->drop_next(can::Filter::exact(0x600 + kNode), 1);  // the next segment is lost
  ASSERT_TRUE(sim.run_until([&] { return r.has_value(); }));
  ASSERT_TRUE(r->ok()) << r->message();
  const OdEntry* e = od.find({0x2005, 0});
  ASSERT_EQ(e->size, 700u);
  EXPECT_TRUE(std::equal(data.begin(), data.end(), od.data(*e)));
  const auto resp = responses();
  ASSERT_GE(resp.size(), 2u);
  EXPECT_EQ(resp[1].data[0], 0xA2);
  EXPECT_LT(resp[1].data[1], 127) << "the acknowledgement names the last segment before the gap";
}

TEST_F(SdoTest, LostBlockUploadSegmentsAreRepeated) {
  const auto data = pattern(500, 11);
  od.write({0x2005, 0}, data.data(), data.size(), false);
  std::optional<SdoResult> r;
  client->upload({0x2005, 0}, [&](const SdoResult& x) { r = x; }, SdoMode::Block);
  ASSERT_TRUE(sim.run_until([&] { return requests().size() >= 2; }));  // start sent
  sim.bus->drop_next(can::Filter::exact(0x580 + kNode), 1);
  ASSERT_TRUE(sim.run_until([&] { return r.has_value(); }));
  ASSERT_TRUE(r->ok()) << r->message();
  EXPECT_EQ(r->data, data);
}

TEST_F(SdoTest, ServerAbortsAreDecoded) {
  struct Case {
    bool upload;
    ObjectAddress addr;
    std::vector<uint8_t> data;
    uint32_t code;
  };
  const Case cases[] = {
      {true, {0x3000, 0}, {}, abort_code::kNoObject},
      {true, {0x2007, 5}, {}, abort_code::kNoSubIndex},
      {true, {0x2004, 0}, {}, abort_code::kWriteOnly},
      {false, {0x2003, 0}, {1, 2, 3, 4}, abort_code::kReadOnly},
      {false, {0x1008, 0}, {'x'}, abort_code::kReadOnly},
      {false, {0x2001, 0}, {1, 0, 0, 0}, abort_code::kLengthTooHigh},
      {false, {0x2001, 0}, {1}, abort_code::kLengthTooLow},
      {false, {0x2001, 0}, {5, 0}, abort_code::kValueTooLow},
      {false, {0x2001, 0}, {0xD0, 0x07}, abort_code::kValueTooHigh},
      {false, {0x2006, 0}, pattern(65), abort_code::kLengthTooHigh},
      {false, {0x2009, 0}, {1, 0, 0, 0}, abort_code::kDeviceState},
      {false, {0x3000, 0}, {1}, abort_code::kNoObject},
  };
  for (const Case& c : cases) {
    const SdoResult r = c.upload ? upload(c.addr) : download(c.addr, c.data);
    EXPECT_EQ(r.abort_code, c.code) << r.message();
    EXPECT_FALSE(r.aborted_by_client);
    const can::Frame last = responses().back();
    EXPECT_EQ(last.data[0], 0x80);
    EXPECT_EQ(get_le<uint32_t>(&last.data[4]), c.code);
    EXPECT_EQ(get_le<uint16_t>(&last.data[1]), c.addr.index);
    EXPECT_EQ(last.data[3], c.addr.sub);
  }
  const SdoResult r = upload({0x3000, 0});
  EXPECT_EQ(r.message(), "SDO upload 0x3000:00 aborted by the device: 0x06020000 object does not exist in the object dictionary");
}

TEST_F(SdoTest, AbortTextsCoverTheReferenceTable) {
  const uint32_t codes[] = {0x05030000, 0x05040000, 0x05040001, 0x05040002, 0x05040003, 0x05040004, 0x05040005,
                            0x06010000, 0x06010001, 0x06010002, 0x06020000, 0x06040041, 0x06040042, 0x06040043,
                            0x06040047, 0x06060000, 0x06070010, 0x06070012, 0x06070013, 0x06090011, 0x06090030,
                            0x06090031, 0x06090032, 0x06090036, 0x060A0023, 0x08000000, 0x08000020, 0x08000021,
                            0x08000022, 0x08000023, 0x08000024};
  for (uint32_t c : codes) EXPECT_STRNE(sdo_abort_text(c), "unknown abort code") << std::hex << c;
  EXPECT_STREQ(sdo_abort_text(0x12345678), "unknown abort code");
}

// --- the server against hand-written requests ---

class SdoServerRaw : public SdoTest {
 protected:
  void SetUp() override {
    SdoTest::SetUp();
    raw = sim.port("raw");
  }
  void request(std::vector<uint8_t> b) {
    b.resize(8, 0);
    raw->send(can::Frame::make(0x600 + kNode, b.data(), 8));
    sim.run_for(2'000'000);
  }
  uint32_t last_abort() const {
    const auto r = responses();
    if (r.empty() || r.back().data[0] != 0x80) return 0;
    return get_le<uint32_t>(&r.back().data[4]);
  }
  std::unique_ptr<can::VirtualPort> raw;
};

TEST_F(SdoServerRaw, WrongToggleInADownloadSegment) {
  request({0x21, 0x05, 0x20, 0x00, 14, 0, 0, 0});
  EXPECT_EQ(responses().back().data[0], 0x60);
  request({0x10, 1, 2, 3, 4, 5, 6, 7});  // t=1 where t=0 is due
  EXPECT_EQ(last_abort(), abort_code::kToggleBit);
}

TEST_F(SdoServerRaw, WrongToggleInAnUploadSegmentRequest) {
  request({0x40, 0x08, 0x10, 0x00});
  EXPECT_EQ(responses().back().data[0], 0x41);
  request({0x60});
  request({0x60});  // the same toggle twice
  EXPECT_EQ(last_abort(), abort_code::kToggleBit);
}

TEST_F(SdoServerRaw, UnknownAndOutOfSequenceCommands) {
  request({0xE0, 0x00, 0x20, 0x00});  // ccs 7 does not exist
  EXPECT_EQ(last_abort(), abort_code::kCommandSpecifier);
  request({0x00, 1, 2, 3, 4, 5, 6, 7});  // a segment without an initiate
  EXPECT_EQ(last_abort(), abort_code::kCommandSpecifier);
  request({0x60});  // an upload segment request without an upload
  EXPECT_EQ(last_abort(), abort_code::kCommandSpecifier);
  request({0xA3});  // block upload start without initiate
  EXPECT_EQ(last_abort(), abort_code::kCommandSpecifier);
}

TEST_F(SdoServerRaw, SegmentedDownloadShorterThanIndicated) {
  request({0x21, 0x05, 0x20, 0x00, 10, 0, 0, 0});
  request({0x00 | (4 << 1) | 1, 1, 2, 3});  // 3 bytes, last
  EXPECT_EQ(last_abort(), abort_code::kLengthMismatch);
}

TEST_F(SdoServerRaw, BlockSequenceNumberAndSizeErrors) {
  node->sdo_server().set_max_block_size(4);
  request({0xC6, 0x05, 0x20, 0x00, 100, 0, 0, 0});
  EXPECT_EQ(responses().back().data[4], 4);
  request({0x09, 1, 2, 3, 4, 5, 6, 7});  // sequence 9 in a block of 4
  EXPECT_EQ(last_abort(), abort_code::kSequenceNumber);
  request({0xA4, 0x05, 0x20, 0x00, 0, 0});  // block upload with block size 0
  EXPECT_EQ(last_abort(), abort_code::kBlockSize);
  request({0xA4, 0x05, 0x20, 0x00, 128, 0});
  EXPECT_EQ(last_abort(), abort_code::kBlockSize);
}

TEST_F(SdoServerRaw, BlockDownloadWithAWrongCrc) {
  request({0xC6, 0x05, 0x20, 0x00, 10, 0, 0, 0});
  request({0x01, 1, 2, 3, 4, 5, 6, 7});
  request({0x82, 8, 9, 10, 0, 0, 0, 0});
  EXPECT_EQ(bytes_of(responses().back()), (std::vector<uint8_t>{0xA2, 2, 127, 0, 0, 0, 0, 0}));
  const uint8_t data[10] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
  const uint16_t crc = crc16_ccitt(0, data, 10);
  request({0xC1 | (4 << 2), static_cast<uint8_t>(crc ^ 1), static_cast<uint8_t>(crc >> 8)});
  EXPECT_EQ(last_abort(), abort_code::kCrc);
  // The same transfer with the right CRC lands.
  request({0xC6, 0x05, 0x20, 0x00, 10, 0, 0, 0});
  request({0x01, 1, 2, 3, 4, 5, 6, 7});
  request({0x82, 8, 9, 10, 0, 0, 0, 0});
  request({0xC1 | (4 << 2), static_cast<uint8_t>(crc), static_cast<uint8_t>(crc >> 8)});
  EXPECT_EQ(responses().back().data[0], 0xA1);
  EXPECT_EQ(od.find({0x2005, 0})->size, 10u);
}

TEST_F(SdoServerRaw, AStalledTransferTimesOut) {
  request({0x21, 0x05, 0x20, 0x00, 14, 0, 0, 0});
  sim.run_for(1'100'000'000);
  EXPECT_EQ(last_abort(), abort_code::kTimeout);
  EXPECT_FALSE(node->sdo_server().busy());
}

TEST_F(SdoServerRaw, ClientAbortEndsTheTransferSilently) {
  request({0x21, 0x05, 0x20, 0x00, 14, 0, 0, 0});
  const std::size_t before = responses().size();
  request({0x80, 0x05, 0x20, 0x00, 0x00, 0x00, 0x04, 0x05});
  EXPECT_EQ(responses().size(), before);
  EXPECT_FALSE(node->sdo_server().busy());
}

TEST_F(SdoServerRaw, ExpeditedWithoutSizeIsAccepted) {
  request({0x22, 0x01, 0x20, 0x00, 0x2C, 0x01, 0xAA, 0xBB});  // 0x22: size not indicated
  EXPECT_EQ(responses().back().data[0], 0x60);
  EXPECT_EQ(od.get<uint16_t>({0x2001, 0}), 300);
}

// --- the client against a scripted server ---

class SdoClientScripted : public ::testing::Test {
 protected:
  void SetUp() override {
    master = sim.port("master");
    server = sim.port("server");
    client = std::make_unique<SdoClient>(*master, kNode);
    sim.actors.push_back([this](int64_t now) {
      can::Frame f;
      while (server->receive(f)) {
        if (f.id == 0x600 + kNode) {
          seen.push_back(f);
          if (script) script(f);
        }
      }
      while (master->receive(f)) client->on_frame(f, now);
      client->poll(now);
    });
  }
  void answer(std::vector<uint8_t> b) {
    b.resize(8, 0);
    server->send(can::Frame::make(0x580 + kNode, b.data(), 8));
  }
  SdoResult run(std::function<void(SdoClient::Done)> start) {
    std::optional<SdoResult> r;
    start([&](const SdoResult& x) { r = x; });
    EXPECT_TRUE(sim.run_until([&] { return r.has_value(); }, 5'000'000'000));
    sim.run_for(1'000'000);  // lets an abort frame reach the server
    return r.value_or(SdoResult{});
  }
  uint32_t client_abort() const {
    if (seen.empty() || seen.back().data[0] != 0x80) return 0;
    return get_le<uint32_t>(&seen.back().data[4]);
  }

  Sim sim;
  std::unique_ptr<can::VirtualPort> master, server;
  std::unique_ptr<SdoClient> client;
  std::function<void(const can::Frame&)> script;
  std::vector<can::Frame> seen;
};

TEST_F(SdoClientScripted, TimeoutSendsAnAbortAndReportsIt) {
  const SdoResult r = run([&](SdoClient::Done d) { client->upload({0x1000, 0}, d); });
  EXPECT_EQ(r.abort_code, abort_code::kTimeout);
  EXPECT_TRUE(r.aborted_by_client);
  EXPECT_EQ(client_abort(), abort_code::kTimeout);
  EXPECT_EQ(r.message(), "SDO upload 0x1000:00 aborted by the master: 0x05040000 SDO protocol timed out");
}

TEST_F(SdoClientScripted, WrongToggleFromTheServer) {
  script = [&](const can::Frame& f) {
    if (f.data[0] == 0x40) answer({0x41, 0x08, 0x10, 0x00, 14});
    else if ((f.data[0] & 0xE0) == 0x60) answer({0x10, 'a', 'b', 'c', 'd', 'e', 'f', 'g'});  // t=1 first: wrong
  };
  const SdoResult r = run([&](SdoClient::Done d) { client->upload({0x1008, 0}, d); });
  EXPECT_EQ(r.abort_code, abort_code::kToggleBit);
  EXPECT_EQ(client_abort(), abort_code::kToggleBit);
}

TEST_F(SdoClientScripted, WrongToggleInADownloadResponse) {
  script = [&](const can::Frame& f) {
    if (f.data[0] == 0x21) answer({0x60, 0x05, 0x20, 0x00});
    else if ((f.data[0] & 0xE0) == 0x00) answer({0x30});  // t=1 for the first segment
  };
  const SdoResult r = run([&](SdoClient::Done d) { client->download({0x2005, 0}, pattern(10), d, SdoMode::Segmented); });
  EXPECT_EQ(r.abort_code, abort_code::kToggleBit);
}

TEST_F(SdoClientScripted, BlockUploadWithABadCrc) {
  script = [&](const can::Frame& f) {
    if (f.data[0] == 0xA4) answer({0xC6, 0x05, 0x20, 0x00, 3});
    else if (f.data[0] == 0xA3) answer({0x81, 1, 2, 3});
    else if (f.data[0] == 0xA2) answer({0xC1 | (4 << 2), 0x12, 0x34});
  };
  const SdoResult r = run([&](SdoClient::Done d) { client->upload({0x2005, 0}, d, SdoMode::Block); });
  EXPECT_EQ(r.abort_code, abort_code::kCrc);
  EXPECT_EQ(client_abort(), abort_code::kCrc);
}

TEST_F(SdoClientScripted, UnexpectedResponsesAndMultiplexers) {
  script = [&](const can::Frame& f) {
    if (f.data[0] == 0x40) answer({0x60, 0x00, 0x10, 0x00});  // a download response to an upload
  };
  EXPECT_EQ(run([&](SdoClient::Done d) { client->upload({0x1000, 0}, d); }).abort_code, abort_code::kCommandSpecifier);
  script = [&](const can::Frame& f) {
    if (f.data[0] == 0x40) answer({0x43, 0x01, 0x10, 0x00, 1, 2, 3, 4});  // answers 0x1001 instead of 0x1000
  };
  EXPECT_EQ(run([&](SdoClient::Done d) { client->upload({0x1000, 0}, d); }).abort_code, abort_code::kGeneral);
}

// A reply for another object is aborted with the general error (CiA 301
// has no better code), and the result names the object the node answered
// for, so that the message says what went wrong.
TEST_F(SdoClientScripted, AReplyForTheWrongObjectNamesTheObjectTheNodeAnsweredFor) {
  script = [&](const can::Frame& f) {
    if (f.data[0] == 0x2B) answer({0x60, 0x17, 0x10, 0x00});  // acknowledges 0x1017:00 instead of 0x1016:01
  };
  const SdoResult r = run([&](SdoClient::Done d) { client->download({0x1016, 1}, {0x10, 0x00}, d); });
  EXPECT_EQ(r.abort_code, abort_code::kGeneral);
  EXPECT_EQ(client_abort(), abort_code::kGeneral);
  ASSERT_TRUE(r.answered_for);
  EXPECT_EQ(*r.answered_for, (ObjectAddress{0x1017, 0}));
  EXPECT_EQ(r.message(),
            "SDO download 0x1016:01 aborted by the master: 0x08000000 general error: the node answered for 0x1017:00");
}

TEST_F(SdoClientScripted, BlockDownloadAcknowledgementBeyondWhatWasSent) {
  script = [&](const can::Frame& f) {
    if (f.data[0] == 0xC6) answer({0xA4, 0x05, 0x20, 0x00, 2});
    else if (f.data[0] == 0x02) answer({0xA2, 5, 2});  // acknowledges 5 of 2
  };
  EXPECT_EQ(run([&](SdoClient::Done d) { client->download({0x2005, 0}, pattern(100), d, SdoMode::Block); }).abort_code,
            abort_code::kSequenceNumber);
  EXPECT_EQ(client_abort(), abort_code::kSequenceNumber);
}

TEST_F(SdoClientScripted, BlockDownloadWithAnInvalidBlockSize) {
  script = [&](const can::Frame& f) {
    if (f.data[0] == 0xC6) answer({0xA4, 0x05, 0x20, 0x00, 0});
  };
  EXPECT_EQ(run([&](SdoClient::Done d) { client->download({0x2005, 0}, pattern(100), d, SdoMode::Block); }).abort_code,
            abort_code::kBlockSize);
}

TEST_F(SdoClientScripted, SegmentedUploadLongerThanIndicated) {
  script = [&](const can::Frame& f) {
    if (f.data[0] == 0x40) answer({0x41, 0x08, 0x10, 0x00, 3});
    else if (f.data[0] == 0x60) answer({0x00, 1, 2, 3, 4, 5, 6, 7});  // 7 bytes, not last
  };
  EXPECT_EQ(run([&](SdoClient::Done d) { client->upload({0x1008, 0}, d); }).abort_code, abort_code::kLengthMismatch);
}

TEST_F(SdoClientScripted, QueuedTransfersRunInOrderAndCancelTogether) {
  std::vector<int> order;
  script = [&](const can::Frame& f) {
    if (f.data[0] == 0x40) answer({0x4F, f.data[1], f.data[2], f.data[3], f.data[1]});
  };
  for (int i = 0; i < 3; ++i) {
    client->upload({static_cast<uint16_t>(0x2000 + i), 0}, [&order](const SdoResult& r) { order.push_back(r.data.at(0)); });
  }
  EXPECT_EQ(client->queued(), 3u);
  ASSERT_TRUE(sim.run_until([&] { return order.size() == 3; }));
  EXPECT_EQ(order, (std::vector<int>{0x00, 0x01, 0x02}));
  script = nullptr;
  std::vector<uint32_t> codes;
  for (int i = 0; i < 3; ++i) client->upload({0x1000, 0}, [&codes](const SdoResult& r) { codes.push_back(r.abort_code); });
  sim.run_for(1'000'000);
  client->cancel_all(abort_code::kGeneral, sim.now());
  EXPECT_EQ(codes, (std::vector<uint32_t>(3, abort_code::kGeneral)));
  EXPECT_TRUE(client->idle());
}

// The bus-load plan gives SDO a share of every cycle (SDO_FRAMES_PER_CYCLE,
// a request and its response); a block download would otherwise put a
// sub-block of 127 frames on the bus at once.
TEST_F(SdoTest, APacedClientSendsNoMoreRequestsPerCycleThanItsShare) {
  auto most_requests_in_one_ms = [&] {
    std::map<int64_t, int> per_cycle;
    int most = 0;
    for (const can::Frame& f : requests()) most = std::max(most, ++per_cycle[f.timestamp_ns / 1'000'000]);
    return most;
  };
  const auto data = pattern(300, 5);
  ASSERT_TRUE(download({0x2005, 0}, data, SdoMode::Block).ok());
  EXPECT_GT(most_requests_in_one_ms(), 5) << "unpaced, a sub-block goes out at the bus's pace (8 frames a ms)";

  SdoPacer pacer(1'000'000, 1);
  SdoClientOptions o;
  o.pacer = &pacer;
  client = std::make_unique<SdoClient>(*master_port, kNode, o);
  sim.log.clear();
  const SdoResult r = download({0x2005, 0}, pattern(300, 9), SdoMode::Block);
  ASSERT_TRUE(r.ok()) << r.message();
  const OdEntry* e = od.find({0x2005, 0});
  ASSERT_EQ(e->size, 300u);
  EXPECT_EQ(od.data(*e)[299], pattern(300, 9)[299]);
  EXPECT_EQ(most_requests_in_one_ms(), 1);
  EXPECT_GT(pacer.deferred(), 40u);
  EXPECT_TRUE(upload({0x2003, 0}).ok()) << "expedited transfers pass at one request a cycle";
}
