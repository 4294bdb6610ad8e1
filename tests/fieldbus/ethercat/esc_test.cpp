// The simulated ESC seen through raw datagrams: addressing modes and
// working counters, the AL state machine and its refusal codes, the SII
// interface, mailbox hand-over and logical addressing through FMMUs.
#include <gtest/gtest.h>

#include <array>
#include <memory>

#include "sim/ethercat/segment.hpp"

namespace cnc::ethercat {
namespace {

struct Line {
  explicit Line(unsigned n) : seg(std::make_shared<sim::Segment>([this] { return t; })) { seg->add_drives(n); }

  struct Reply {
    uint16_t wkc = 0;
    uint16_t adp = 0;
    std::array<uint8_t, 256> data{};
  };
  Reply dg(Command c, uint16_t adp, uint16_t ado, const std::vector<uint8_t>& data, uint16_t len = 0) {
    return dg32(c, physical_address(adp, ado), data, len);
  }
  Reply dg32(Command c, uint32_t address, const std::vector<uint8_t>& data, uint16_t len = 0) {
    std::array<uint8_t, kMaxFrame> f{};
    FrameBuilder fb;
    fb.begin(f.data(), mac);
    const uint16_t n = len ? len : static_cast<uint16_t>(data.size());
    std::vector<uint8_t> d(data);
    d.resize(n);
    fb.add(c, 1, address, n, d.data());
    const std::size_t size = fb.finish();
    Reply r;
    if (!seg->process(f.data(), size)) return r;
    FrameView v;
    if (parse_frame(f.data(), size, v) != ParseResult::Ok) return r;
    r.wkc = v.datagrams[0].wkc();
    r.adp = v.datagrams[0].adp();
    std::copy(v.datagrams[0].data(), v.datagrams[0].data() + std::min<uint16_t>(n, 256), r.data.begin());
    return r;
  }
  void stations() {
    for (unsigned p = 0; p < seg->size(); ++p) {
      dg(Command::APWR, auto_increment_address(p), reg::kStationAddress, {static_cast<uint8_t>(0x01 + p), 0x10});
    }
  }
  uint16_t al_status(uint16_t station) { return get16(dg(Command::FPRD, station, reg::kAlStatus, {}, 2).data.data()); }
  uint16_t al_code(uint16_t station) { return get16(dg(Command::FPRD, station, reg::kAlStatusCode, {}, 2).data.data()); }
  void request(uint16_t station, uint8_t state) { dg(Command::FPWR, station, reg::kAlControl, {state, 0}); }
  void mailbox_sms(uint16_t station) {
    std::vector<uint8_t> sms(16);
    SmEntry{0x1000, 128, 0x26, 0, 1, 0}.encode(sms.data());
    SmEntry{0x1080, 128, 0x22, 0, 1, 0}.encode(sms.data() + 8);
    dg(Command::FPWR, station, reg::kSm0, sms);
  }

  int64_t t = 1'000'000;
  Mac mac = {2, 0, 0, 0, 0, 9};
  std::shared_ptr<sim::Segment> seg;
};

TEST(EthercatEsc, BroadcastReadCountsSlaves) {
  Line l(4);
  const auto r = l.dg(Command::BRD, 0, reg::kType, {}, 2);
  EXPECT_EQ(r.wkc, 4);
  EXPECT_EQ(r.adp, 4);  // every slave increments ADP
  EXPECT_EQ(r.data[0], 0x11);
}

TEST(EthercatEsc, AutoIncrementAddressesOnePosition) {
  Line l(3);
  const auto r = l.dg(Command::APWR, auto_increment_address(1), reg::kStationAddress, {0x34, 0x12});
  EXPECT_EQ(r.wkc, 1);
  EXPECT_EQ(r.adp, 2);  // 0xFFFF + 3 slaves
  EXPECT_EQ(l.seg->slave(1).station_address(), 0x1234);
  EXPECT_EQ(l.seg->slave(0).station_address(), 0);
  EXPECT_EQ(l.dg(Command::APRD, auto_increment_address(5), reg::kType, {}, 1).wkc, 0);  // behind the last slave
}

TEST(EthercatEsc, ConfiguredAddressAndReadWriteCounters) {
  Line l(3);
  l.stations();
  EXPECT_EQ(l.dg(Command::FPRD, 0x1002, reg::kStationAddress, {}, 2).wkc, 1);
  EXPECT_EQ(get16(l.dg(Command::FPRD, 0x1002, reg::kStationAddress, {}, 2).data.data()), 0x1002);
  EXPECT_EQ(l.dg(Command::FPRD, 0x1009, reg::kStationAddress, {}, 2).wkc, 0);  // nobody there
  const auto rw = l.dg(Command::FPRW, 0x1003, reg::kEventMask, {0xAA, 0x55});
  EXPECT_EQ(rw.wkc, 3);                    // read + write
  EXPECT_EQ(get16(rw.data.data()), 0);     // the old value comes back
  EXPECT_EQ(get16(l.dg(Command::FPRD, 0x1003, reg::kEventMask, {}, 2).data.data()), 0x55AA);
  EXPECT_EQ(l.dg(Command::BWR, 0, reg::kEventMask, {1, 0}).wkc, 3);
  EXPECT_EQ(l.dg(Command::BRW, 0, reg::kEventMask, {2, 0}).wkc, 9);
  // Identity registers are read-only.
  l.dg(Command::FPWR, 0x1001, reg::kType, {0x99});
  EXPECT_EQ(l.dg(Command::FPRD, 0x1001, reg::kType, {}, 1).data[0], 0x11);
}

TEST(EthercatEsc, BroadcastReadOrsTheSlavesBytes) {
  Line l(2);
  l.dg(Command::APWR, auto_increment_address(0), reg::kEventMask, {0x01, 0});
  l.dg(Command::APWR, auto_increment_address(1), reg::kEventMask, {0x80, 0});
  EXPECT_EQ(l.dg(Command::BRD, 0, reg::kEventMask, {}, 1).data[0], 0x81);
}

TEST(EthercatEsc, AlStateMachineAndRefusalCodes) {
  Line l(1);
  l.stations();
  EXPECT_EQ(l.al_status(0x1001), 0x01);  // INIT
  l.request(0x1001, 4);                  // INIT -> SAFEOP: not allowed
  EXPECT_EQ(l.al_status(0x1001), 0x11);
  EXPECT_EQ(l.al_code(0x1001), al::kInvalidStateChange);
  l.request(0x1001, 2);  // without acknowledge: ignored while the error is shown
  EXPECT_EQ(l.al_status(0x1001), 0x11);
  l.request(0x1001, 0x12);  // PREOP with acknowledge, but no mailbox SMs
  EXPECT_EQ(l.al_status(0x1001), 0x11);
  EXPECT_EQ(l.al_code(0x1001), al::kInvalidMailboxPreop);
  l.request(0x1001, 0x15);
  EXPECT_EQ(l.al_code(0x1001), al::kUnknownState);
  l.request(0x1001, 0x13);
  EXPECT_EQ(l.al_code(0x1001), al::kBootNotSupported);
  l.mailbox_sms(0x1001);
  l.request(0x1001, 0x12);
  EXPECT_EQ(l.al_status(0x1001), 0x02);
  EXPECT_EQ(l.al_code(0x1001), 0);
  l.request(0x1001, 8);  // PREOP -> OP skips SAFEOP
  EXPECT_EQ(l.al_code(0x1001), al::kInvalidStateChange);
  l.request(0x1001, 0x14);  // PREOP -> SAFEOP: default mapping needs SM2/SM3 of 7 and 9 bytes
  EXPECT_EQ(l.al_status(0x1001), 0x12);
  EXPECT_EQ(l.al_code(0x1001), al::kInvalidOutputConfig);
  std::vector<uint8_t> sms(16);
  SmEntry{0x1100, 7, 0x64, 0, 1, 0}.encode(sms.data());
  SmEntry{0x1180, 9, 0x20, 0, 1, 0}.encode(sms.data() + 8);
  l.dg(Command::FPWR, 0x1001, reg::kSm0 + 16, sms);
  l.request(0x1001, 0x14);
  EXPECT_EQ(l.al_status(0x1001), 0x04);
  l.request(0x1001, 0x08);  // no outputs yet
  EXPECT_EQ(l.al_status(0x1001), 0x14);
  EXPECT_EQ(l.al_code(0x1001), al::kNoValidOutputs);
  l.dg(Command::FPWR, 0x1001, 0x1100, std::vector<uint8_t>(7, 0));
  l.request(0x1001, 0x18);
  EXPECT_EQ(l.al_status(0x1001), 0x08);
  l.request(0x1001, 0x01);  // any state -> INIT
  EXPECT_EQ(l.al_status(0x1001), 0x01);
}

TEST(EthercatEsc, InjectedRefusal) {
  Line l(1);
  l.stations();
  l.seg->slave(0).refuse_state(AlState::PreOp, 0x8123);
  l.mailbox_sms(0x1001);
  l.request(0x1001, 0x02);
  EXPECT_EQ(l.al_status(0x1001), 0x11);
  EXPECT_EQ(l.al_code(0x1001), 0x8123);
}

TEST(EthercatEsc, SiiReadThroughTheInterfaceRegisters) {
  Line l(2);
  l.stations();
  std::vector<uint8_t> cmd(6);
  put16(cmd.data(), sii::kRead);
  put32(cmd.data() + 2, 0x0008);  // vendor ID, product code
  EXPECT_EQ(l.dg(Command::FPWR, 0x1002, reg::kSiiControl, cmd).wkc, 1);
  const auto st = l.dg(Command::FPRD, 0x1002, reg::kSiiControl, {}, 2);
  EXPECT_EQ(get16(st.data.data()) & sii::kBusy, 0);
  EXPECT_NE(get16(st.data.data()) & sii::kRead8, 0);
  const auto d = l.dg(Command::FPRD, 0x1002, reg::kSiiData, {}, 8);
  EXPECT_EQ(get32(d.data.data()), 0x00000CC1u);
  EXPECT_EQ(get32(d.data.data() + 4), 0x00000402u);
  put32(cmd.data() + 2, 0x100000);  // beyond the image
  l.dg(Command::FPWR, 0x1002, reg::kSiiControl, cmd);
  EXPECT_NE(get16(l.dg(Command::FPRD, 0x1002, reg::kSiiControl, {}, 2).data.data()) & sii::kError, 0);
}

TEST(EthercatEsc, EmptyMailboxIsNotReadAndFullOneIsHandedOver) {
  Line l(1);
  l.stations();
  l.mailbox_sms(0x1001);
  l.request(0x1001, 0x02);
  EXPECT_EQ(l.dg(Command::FPRD, 0x1001, 0x1080, {}, 128).wkc, 0);  // empty: no WKC
  // An SDO upload request of 0x1018:01 (vendor ID).
  std::vector<uint8_t> m(128, 0);
  MailboxHeader h;
  h.length = 10;
  h.counter = 1;
  h.encode(m.data());
  put16(m.data() + 6, coe_header(CoeService::SdoRequest));
  m[8] = 0x40;
  put16(m.data() + 9, 0x1018);
  m[11] = 1;
  EXPECT_EQ(l.dg(Command::FPWR, 0x1001, 0x1000, m).wkc, 1);
  EXPECT_EQ(l.dg(Command::FPRD, 0x1001, reg::kSm0 + 13, {}, 1).data[0] & sm::kStatusFull, sm::kStatusFull);
  const auto r = l.dg(Command::FPRD, 0x1001, 0x1080, {}, 128);
  EXPECT_EQ(r.wkc, 1);
  EXPECT_EQ(coe_service(get16(r.data.data() + 6)), CoeService::SdoResponse);
  EXPECT_EQ(r.data[8], 0x43);  // expedited, 4 bytes
  EXPECT_EQ(get32(r.data.data() + 12), 0x00000CC1u);
  EXPECT_EQ(l.dg(Command::FPRD, 0x1001, reg::kSm0 + 13, {}, 1).data[0] & sm::kStatusFull, 0);
  // Another protocol than CoE: mailbox error "unsupported protocol".
  put16(m.data(), 10);
  m[5] = 0x14;  // FoE
  l.dg(Command::FPWR, 0x1001, 0x1000, m);
  const auto e = l.dg(Command::FPRD, 0x1001, 0x1080, {}, 128);
  EXPECT_EQ(e.data[5] & 0x0F, 0);  // type 0: error
  EXPECT_EQ(get16(e.data.data() + 8), 2);
}

TEST(EthercatEsc, LogicalAddressingThroughFmmus) {
  Line l(2);
  l.stations();
  for (uint16_t s : {0x1001, 0x1002}) {
    std::vector<uint8_t> f(32);
    FmmuEntry out;
    out.logical_start = 0x100 + (s - 0x1001) * 4;
    out.length = 4;
    out.physical_start = 0x1100;
    out.type = 2;
    out.activate = 1;
    out.encode(f.data());
    FmmuEntry in = out;
    in.logical_start = 0x200 + (s - 0x1001) * 4;
    in.physical_start = 0x1180;
    in.type = 1;
    in.encode(f.data() + 16);
    l.dg(Command::FPWR, s, reg::kFmmu0, f);
    l.dg(Command::FPWR, s, 0x1180, {static_cast<uint8_t>(s), 0xBE, 0xEF, 0x00});
  }
  const auto w = l.dg32(Command::LWR, 0x100, {1, 2, 3, 4, 5, 6, 7, 8});
  EXPECT_EQ(w.wkc, 2);
  EXPECT_EQ(l.dg(Command::FPRD, 0x1002, 0x1100, {}, 4).data[0], 5);
  const auto r = l.dg32(Command::LRD, 0x200, {}, 8);
  EXPECT_EQ(r.wkc, 2);
  EXPECT_EQ(r.data[0], 0x01);
  EXPECT_EQ(r.data[4], 0x02);
  EXPECT_EQ(l.dg32(Command::LRW, 0x0FC, {}, 0x110).wkc, 6);  // both windows of both slaves
  EXPECT_EQ(l.dg32(Command::LRW, 0x300, {}, 8).wkc, 0);      // nothing mapped there
}

TEST(EthercatEsc, ArmwReadsAtTheAddressedSlaveAndWritesBehindIt) {
  Line l(3);
  l.stations();
  l.dg(Command::FPWR, 0x1001, reg::kEventMask, {0x5A, 0});
  const auto r = l.dg(Command::FRMW, 0x1001, reg::kEventMask, {}, 2);
  EXPECT_EQ(r.wkc, 3);
  EXPECT_EQ(r.data[0], 0x5A);
  EXPECT_EQ(l.dg(Command::FPRD, 0x1003, reg::kEventMask, {}, 1).data[0], 0x5A);
  EXPECT_EQ(l.dg(Command::ARMW, auto_increment_address(1), reg::kEventMask, {}, 2).wkc, 3);
}

TEST(EthercatEsc, CableBreakHidesTheSlavesBehindIt) {
  Line l(3);
  l.seg->break_after(1);
  EXPECT_EQ(l.dg(Command::BRD, 0, reg::kType, {}, 1).wkc, 1);
  // DL status of the last reachable slave: port 1 without communication.
  l.stations();
  EXPECT_EQ(get16(l.dg(Command::FPRD, 0x1001, reg::kDlStatus, {}, 2).data.data()) & 0x0800, 0);
  l.seg->break_after(0);
  EXPECT_NE(get16(l.dg(Command::FPRD, 0x1001, reg::kDlStatus, {}, 2).data.data()) & 0x0800, 0);
  l.seg->drop_frames(1);
  EXPECT_EQ(l.dg(Command::BRD, 0, reg::kType, {}, 1).wkc, 0);
  EXPECT_EQ(l.seg->frames_dropped(), 1u);
}

// The slaves' clock thread (ethercat_sim) polls them only while no frame
// reaches them all: each frame polls the slaves it passes, and the thread
// keeps off the lock the master's servo thread sends under.
TEST(EthercatEsc, ClockThreadPollsOnlyWhileNoFramesPassEverySlave) {
  Line l(2);
  EXPECT_TRUE(l.seg->poll_if_idle()) << "no frame yet";
  l.dg(Command::BRD, 0, reg::kType, {}, 1);
  EXPECT_FALSE(l.seg->poll_if_idle()) << "a frame passed every slave since";
  EXPECT_TRUE(l.seg->poll_if_idle()) << "none since the previous call";
  l.seg->drop_frames(1);
  l.dg(Command::BRD, 0, reg::kType, {}, 1);
  EXPECT_TRUE(l.seg->poll_if_idle()) << "a lost frame reaches no slave";
  l.seg->break_after(1);
  l.dg(Command::BRD, 0, reg::kType, {}, 1);
  EXPECT_TRUE(l.seg->poll_if_idle()) << "slaves behind a cable break see no frames";
}

}  // namespace
}  // namespace cnc::ethercat
