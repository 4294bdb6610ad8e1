#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "fieldbus/can/error_frame.hpp"
#include "fieldbus/can/frame.hpp"
#include "fieldbus/can/transport.hpp"

using namespace cnc::can;

TEST(Frame, MakeLimitsClassicFramesToEightBytes) {
  const Frame f = Frame::make(0x7FF, {1, 2, 3, 4, 5, 6, 7, 8, 9});
  EXPECT_EQ(f.len, 8);
  EXPECT_EQ(f.data[7], 8);
  EXPECT_TRUE(is_valid_length(f));
  EXPECT_EQ(Frame::make(0x1234, {}).id, 0x234u) << "standard identifiers keep 11 bits";
}

TEST(Frame, FdLengthsFollowTheDlcSteps) {
  EXPECT_EQ(fd_len_to_dlc(8), 8);
  EXPECT_EQ(fd_len_to_dlc(9), 9);
  EXPECT_EQ(fd_len_to_dlc(12), 9);
  EXPECT_EQ(fd_len_to_dlc(13), 10);
  EXPECT_EQ(fd_len_to_dlc(64), 15);
  EXPECT_EQ(fd_dlc_to_len(13), 32u);
  Frame f;
  f.flags = kFd;
  f.len = 12;
  EXPECT_TRUE(is_valid_length(f));
  f.len = 13;
  EXPECT_FALSE(is_valid_length(f));
  f.flags = 0;
  f.len = 12;
  EXPECT_FALSE(is_valid_length(f));
}

TEST(Frame, FormatsForLogs) {
  char buf[64];
  EXPECT_STREQ(format(Frame::make(0x181, {0x27, 0x02}), buf, sizeof buf), "0x181 [2] 27 02");
  EXPECT_STREQ(format(Frame::remote(0x705, 1), buf, sizeof buf), "0x705 RTR [1]");
  Frame e;
  e.flags = kExtended;
  e.id = 0x18FF0001;
  EXPECT_STREQ(format(e, buf, sizeof buf), "0x18FF0001 [0]");
}

TEST(Filter, MatchesWithMaskAndKind) {
  const Filter tpdos = Filter::range_mask(0x180, 0x780);  // 0x180..0x1FF
  EXPECT_TRUE(tpdos.matches(Frame::make(0x185, {})));
  EXPECT_FALSE(tpdos.matches(Frame::make(0x285, {})));
  Frame ext = Frame::make(0x185, {});
  ext.flags = kExtended;
  EXPECT_FALSE(tpdos.matches(ext));
  EXPECT_FALSE(tpdos.matches(make_error_frame(kErrBusOff)));
}

TEST(ErrorFrames, StateTrackerFollowsControllerReports) {
  BusStateTracker t;
  EXPECT_EQ(t.state(), BusState::ErrorActive);
  EXPECT_TRUE(t.on_error_frame(make_error_frame(kErrController, kCtrlTxWarning)));
  EXPECT_EQ(t.state(), BusState::ErrorWarning);
  EXPECT_TRUE(t.on_error_frame(make_error_frame(kErrController, kCtrlTxPassive)));
  EXPECT_EQ(t.state(), BusState::ErrorPassive);
  EXPECT_TRUE(t.on_error_frame(make_error_frame(kErrBusOff)));
  EXPECT_EQ(t.state(), BusState::BusOff);
  EXPECT_FALSE(t.on_error_frame(make_error_frame(kErrProtocol | kErrCounters, 0, kProtBit, 10, 0)))
      << "only a restart ends bus-off";
  EXPECT_TRUE(t.on_error_frame(make_error_frame(kErrRestarted)));
  EXPECT_EQ(t.state(), BusState::ErrorActive);
  EXPECT_FALSE(t.on_error_frame(Frame::make(0x80, {})));
}

TEST(ErrorFrames, DecodeAndDescribe) {
  const Frame f = make_error_frame(kErrController | kErrCounters, kCtrlRxPassive | kCtrlRxOverflow, 0, 3, 130);
  const ErrorInfo e = decode_error_frame(f);
  EXPECT_TRUE(e.has_counters);
  EXPECT_EQ(e.tx_errors, 3);
  EXPECT_EQ(e.rx_errors, 130);
  char buf[128];
  EXPECT_STREQ(describe_error(e, buf, sizeof buf), "RX error-passive, RX buffer overflow");
  EXPECT_STREQ(describe_error(decode_error_frame(make_error_frame(kErrBusOff)), buf, sizeof buf), "bus-off");
  EXPECT_EQ(bus_state_from_counters(95, 0), BusState::ErrorActive);
  EXPECT_EQ(bus_state_from_counters(0, 96), BusState::ErrorWarning);
  EXPECT_EQ(bus_state_from_counters(128, 0), BusState::ErrorPassive);
  EXPECT_EQ(bus_state_from_counters(256, 0), BusState::BusOff);
}

TEST(OpenTransport, RejectsUnknownSpecifications) {
  EXPECT_THROW(open_transport("can0"), std::runtime_error);
  EXPECT_THROW(open_transport("serial:ttyS0"), std::runtime_error);
  EXPECT_THROW(open_transport("socketcan:can0,speed=1"), std::runtime_error);
}

// The product knows SocketCAN only; other kinds come from whoever
// registers them (the simulators register "virtual").
TEST(OpenTransport, OpensARegisteredKindWithItsNameAndOptions) {
  static std::string seen;
  register_transport_kind("Test-Kind", [](std::string_view spec, const std::string& name,
                                          const std::vector<std::string>& options) -> std::unique_ptr<Transport> {
    seen = std::string(spec) + "|" + name;
    for (const auto& o : options) seen += "|" + o;
    throw std::runtime_error("opened");
  });
  try {
    open_transport("test-kind: bus-a , x=1,  y ");
    FAIL() << "the registered opener was not called";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "opened");
  }
  EXPECT_EQ(seen, "test-kind: bus-a , x=1,  y |bus-a|x=1|y");
  try {
    open_transport("nosuch:x");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("unknown kind \"nosuch\""), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("test-kind"), std::string::npos) << e.what();
  }
}
