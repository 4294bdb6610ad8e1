// SocketCAN transport against the real kernel stack (vcan0/vcan1, created
// by scripts/vm/run.sh in a VM or a private network namespace). Skipped
// where the kernel has no AF_CAN or no vcan0.
#include <gtest/gtest.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <net/if.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdlib>
#include <stdexcept>
#include <vector>

#include "core/util/time.hpp"
#include "fieldbus/can/socketcan.hpp"

using namespace cnc;
using namespace cnc::can;

namespace {

bool have_vcan() { return SocketCanTransport::available() && ::if_nametoindex("vcan0") != 0; }

#define REQUIRE_VCAN()                                                              \
  do {                                                                              \
    if (!have_vcan()) GTEST_SKIP() << "no AF_CAN or no vcan0 (run via scripts/vm)"; \
  } while (0)

bool receive_within(Transport& t, Frame& f, int64_t timeout_ns = 1'000'000'000) {
  const int64_t end = monotonic_ns() + timeout_ns;
  while (monotonic_ns() < end) {
    if (t.receive(f)) return true;
    t.wait(10'000'000);
  }
  return false;
}

std::vector<Frame> drain(Transport& t, int64_t settle_ns = 50'000'000) {
  std::vector<Frame> out;
  Frame f;
  const int64_t end = monotonic_ns() + settle_ns;
  while (monotonic_ns() < end) {
    while (t.receive(f)) out.push_back(f);
    t.wait(5'000'000);
  }
  while (t.receive(f)) out.push_back(f);
  return out;
}

// Writes a raw kernel frame (error frames cannot go through the transport).
void inject(const std::string& ifname, canid_t id, std::vector<uint8_t> data) {
  const int s = ::socket(PF_CAN, SOCK_RAW, CAN_RAW);
  ASSERT_GE(s, 0);
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = static_cast<int>(::if_nametoindex(ifname.c_str()));
  ASSERT_EQ(::bind(s, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  can_frame k{};
  k.can_id = id;
  k.len = static_cast<uint8_t>(data.size());
  for (std::size_t i = 0; i < data.size(); ++i) k.data[i] = data[i];
  ASSERT_EQ(::write(s, &k, sizeof k), static_cast<ssize_t>(sizeof k));
  ::close(s);
}

}  // namespace

TEST(SocketCan, FramesCrossBetweenSockets) {
  REQUIRE_VCAN();
  SocketCanTransport a("vcan0"), b("vcan0");
  EXPECT_EQ(a.name(), "socketcan:vcan0");
  std::vector<Frame> sent;
  for (uint8_t n = 0; n <= 8; ++n) {
    Frame f = Frame::make(0x100 + n, {});
    f.len = n;
    for (uint8_t i = 0; i < n; ++i) f.data[i] = static_cast<uint8_t>(n * 16 + i);
    sent.push_back(f);
  }
  Frame ext;
  ext.flags = kExtended;
  ext.id = 0x18FEF100;
  ext.len = 2;
  ext.data[0] = 0xAB;
  sent.push_back(ext);
  sent.push_back(Frame::remote(0x705, 1));
  const int64_t before = monotonic_ns();
  for (const auto& f : sent) ASSERT_EQ(a.send(f), SendStatus::Ok);
  std::vector<Frame> got;
  Frame f;
  while (got.size() < sent.size() && receive_within(b, f)) got.push_back(f);
  const int64_t after = monotonic_ns();
  ASSERT_EQ(got.size(), sent.size());
  for (std::size_t i = 0; i < sent.size(); ++i) {
    EXPECT_TRUE(same_content(got[i], sent[i])) << i;
    EXPECT_GE(got[i].timestamp_ns, before - 1'000'000) << "kernel timestamps in CLOCK_MONOTONIC";
    EXPECT_LE(got[i].timestamp_ns, after + 1'000'000);
    if (i > 0) {
      EXPECT_GE(got[i].timestamp_ns, got[i - 1].timestamp_ns);
    }
  }
  EXPECT_TRUE(drain(a).empty()) << "a socket does not hear itself by default";
  EXPECT_EQ(a.stats().tx_frames, sent.size());
  EXPECT_EQ(b.stats().rx_frames, sent.size());
}

TEST(SocketCan, ReceiveOwnWhenAsked) {
  REQUIRE_VCAN();
  SocketCanOptions o;
  o.receive_own = true;
  SocketCanTransport a("vcan0", o);
  ASSERT_EQ(a.send(Frame::make(0x123, {1})), SendStatus::Ok);
  Frame f;
  ASSERT_TRUE(receive_within(a, f));
  EXPECT_EQ(f.id, 0x123u);
}

TEST(SocketCan, FiltersSelectFrames) {
  REQUIRE_VCAN();
  SocketCanTransport a("vcan0"), b("vcan0");
  const Filter tpdos[] = {Filter::range_mask(0x180, 0x780), Filter::exact(0x701)};
  b.set_filters(tpdos);
  for (uint32_t id : {0x181u, 0x201u, 0x1FFu, 0x701u, 0x702u}) a.send(Frame::make(id, {0}));
  std::vector<uint32_t> ids;
  for (const auto& f : drain(b)) ids.push_back(f.id);
  EXPECT_EQ(ids, (std::vector<uint32_t>{0x181, 0x1FF, 0x701}));
  b.set_filters({});
  a.send(Frame::make(0x201, {0}));
  EXPECT_EQ(drain(b).size(), 1u);
}

TEST(SocketCan, ReceiveNeverBlocksAndWaitTimesOut) {
  REQUIRE_VCAN();
  SocketCanTransport a("vcan0"), b("vcan0");
  Frame f;
  const int64_t t0 = monotonic_ns();
  EXPECT_FALSE(b.receive(f));
  EXPECT_FALSE(b.wait(20'000'000));
  EXPECT_GE(monotonic_ns() - t0, 15'000'000);
  a.send(Frame::make(0x10, {}));
  EXPECT_TRUE(b.wait(1'000'000'000));
  EXPECT_TRUE(b.receive(f));
}

TEST(SocketCan, FdFramesOnlyWhereEnabled) {
  REQUIRE_VCAN();
  SocketCanOptions fd;
  fd.fd = true;
  SocketCanTransport a("vcan0", fd), b("vcan0", fd), classic("vcan0");
  Frame f;
  f.id = 0x300;
  f.flags = kFd | kBitRateSwitch;
  f.len = 64;
  for (int i = 0; i < 64; ++i) f.data[i] = static_cast<uint8_t>(i);
  EXPECT_EQ(classic.send(f), SendStatus::Invalid) << "FD not enabled on this socket";
  ASSERT_EQ(a.send(f), SendStatus::Ok);
  Frame g;
  ASSERT_TRUE(receive_within(b, g));
  EXPECT_TRUE(g.is_fd());
  EXPECT_TRUE(g.flags & kBitRateSwitch);
  EXPECT_EQ(g.len, 64);
  EXPECT_EQ(g.data[63], 63);
  EXPECT_TRUE(drain(classic).empty()) << "classic sockets do not get FD frames";
}

TEST(SocketCan, ErrorFramesReportErrorPassiveBusOffAndRecovery) {
  REQUIRE_VCAN();
  SocketCanTransport t("vcan0");
  Frame f;
  inject("vcan0", CAN_ERR_FLAG | CAN_ERR_CRTL, {0, CAN_ERR_CRTL_TX_PASSIVE, 0, 0, 0, 0, 0, 0});
  ASSERT_TRUE(receive_within(t, f));
  EXPECT_TRUE(f.is_error());
  EXPECT_EQ(t.state(), BusState::ErrorPassive);
  inject("vcan0", CAN_ERR_FLAG | CAN_ERR_BUSOFF, {0, 0, 0, 0, 0, 0, 0, 0});
  ASSERT_TRUE(receive_within(t, f));
  EXPECT_TRUE(decode_error_frame(f).classes & kErrBusOff);
  EXPECT_EQ(t.state(), BusState::BusOff);
  inject("vcan0", CAN_ERR_FLAG | CAN_ERR_RESTARTED, {0, 0, 0, 0, 0, 0, 0, 0});
  ASSERT_TRUE(receive_within(t, f));
  EXPECT_EQ(t.state(), BusState::ErrorActive);
  EXPECT_EQ(t.stats().error_frames, 3u);
  SocketCanTransport quiet("vcan0");
  quiet.set_error_reports(false);
  inject("vcan0", CAN_ERR_FLAG | CAN_ERR_BUSOFF, {0, 0, 0, 0, 0, 0, 0, 0});
  EXPECT_TRUE(drain(quiet).empty());
  EXPECT_EQ(quiet.state(), BusState::ErrorActive);
}

TEST(SocketCan, InterfaceDownIsReported) {
  REQUIRE_VCAN();
  if (::if_nametoindex("vcan1") == 0 || ::getuid() != 0) GTEST_SKIP() << "needs vcan1 and root";
  SocketCanTransport t("vcan1");
  ASSERT_EQ(std::system("ip link set vcan1 down"), 0);
  EXPECT_EQ(t.send(Frame::make(0x1, {})), SendStatus::Down);
  ASSERT_EQ(std::system("ip link set vcan1 up"), 0);
  EXPECT_EQ(t.send(Frame::make(0x1, {})), SendStatus::Ok);
}

TEST(SocketCan, OpeningADownInterfaceSaysHowToBringItUp) {
  REQUIRE_VCAN();
  if (::if_nametoindex("vcan1") == 0 || ::getuid() != 0) GTEST_SKIP() << "needs vcan1 and root";
  ASSERT_EQ(std::system("ip link set vcan1 down"), 0);
  try {
    SocketCanTransport t("vcan1", SocketCanOptions{.expected_bitrate = 500000});
    ADD_FAILURE() << "opened a down interface";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("SocketCAN vcan1: the interface is down"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("cnc-can-up vcan1 500000"), std::string::npos) << e.what();
  }
  ASSERT_EQ(std::system("ip link set vcan1 up"), 0);
  // vcan has no bit timing: any configured bitrate is accepted.
  SocketCanTransport up("vcan1", SocketCanOptions{.expected_bitrate = 500000});
  EXPECT_EQ(up.bitrate(), 0u);
}

TEST(SocketCan, OpeningAMissingInterfaceSaysWhich) {
  if (!SocketCanTransport::available()) GTEST_SKIP() << "no AF_CAN";
  try {
    SocketCanTransport t("nosuchcan7");
    FAIL();
  } catch (const std::system_error& e) {
    EXPECT_NE(std::string(e.what()).find("SocketCAN nosuchcan7: no such interface"), std::string::npos) << e.what();
  }
}

TEST(SocketCan, UnavailableKernelIsAClearError) {
  if (SocketCanTransport::available()) GTEST_SKIP() << "this kernel has AF_CAN";
  EXPECT_THROW(SocketCanTransport("vcan0"), std::system_error);
}
