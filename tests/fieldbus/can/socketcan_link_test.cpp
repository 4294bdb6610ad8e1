// What the SocketCAN transport learns about an interface before using it:
// the bitrate in the kernel's link message, the bitrate a spec asks for.
#include <gtest/gtest.h>
#include <linux/can/netlink.h>
#include <linux/netlink.h>
#include <linux/rtnetlink.h>

#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "fieldbus/can/socketcan.hpp"
#include "fieldbus/can/transport.hpp"

namespace cnc::can {
namespace {

// Appends an rtattr of `type` holding `payload`, aligned as the kernel does.
void put_attr(std::vector<uint8_t>& m, unsigned short type, const void* payload, std::size_t len) {
  rtattr a{};
  a.rta_len = static_cast<unsigned short>(RTA_LENGTH(len));
  a.rta_type = type;
  const std::size_t at = m.size();
  m.resize(at + RTA_SPACE(len), 0);
  std::memcpy(m.data() + at, &a, sizeof a);
  if (len) std::memcpy(m.data() + at + RTA_LENGTH(0), payload, len);
}

// An RTM_NEWLINK message as the kernel sends for a CAN interface at
// `bitrate` (with_timing false: as for vcan, no IFLA_INFO_DATA).
std::vector<uint8_t> link_message(uint32_t bitrate, bool with_timing = true) {
  std::vector<uint8_t> timing;
  can_bittiming bt{};
  bt.bitrate = bitrate;
  bt.sample_point = 875;
  put_attr(timing, IFLA_CAN_BITTIMING, &bt, sizeof bt);
  std::vector<uint8_t> info;
  put_attr(info, IFLA_INFO_KIND, "can", 4);
  if (with_timing) put_attr(info, IFLA_INFO_DATA, timing.data(), timing.size());
  std::vector<uint8_t> attrs;
  put_attr(attrs, IFLA_IFNAME, "can0", 5);
  put_attr(attrs, IFLA_LINKINFO | NLA_F_NESTED, info.data(), info.size());

  const std::size_t head = NLMSG_ALIGN(NLMSG_LENGTH(sizeof(ifinfomsg)));
  std::vector<uint8_t> m(head + attrs.size(), 0);
  std::memcpy(m.data() + head, attrs.data(), attrs.size());
  nlmsghdr h{};
  h.nlmsg_len = static_cast<uint32_t>(m.size());
  h.nlmsg_type = RTM_NEWLINK;
  std::memcpy(m.data(), &h, sizeof h);
  return m;
}

TEST(SocketCanLink, BitrateIsReadFromTheKernelsLinkMessage) {
  EXPECT_EQ(can_bitrate_in_link_message(link_message(500000)), 500000u);
  EXPECT_EQ(can_bitrate_in_link_message(link_message(1000000)), 1000000u);
}

TEST(SocketCanLink, InterfaceWithoutBitTimingHasNoBitrate) {
  EXPECT_EQ(can_bitrate_in_link_message(link_message(500000, false)), 0u);
}

TEST(SocketCanLink, TruncatedOrOtherMessagesHaveNoBitrate) {
  auto m = link_message(500000);
  EXPECT_EQ(can_bitrate_in_link_message({m.data(), m.size() - 8}), 0u);  // shorter than nlmsg_len
  EXPECT_EQ(can_bitrate_in_link_message({m.data(), 10}), 0u);
  nlmsghdr h;
  std::memcpy(&h, m.data(), sizeof h);
  h.nlmsg_type = NLMSG_ERROR;
  std::memcpy(m.data(), &h, sizeof h);
  EXPECT_EQ(can_bitrate_in_link_message(m), 0u);
}

TEST(SocketCanLink, SpecBitrateThatIsNotANumberIsRefusedBeforeOpening) {
  try {
    open_transport("socketcan:can0,bitrate=fast");
    FAIL() << "accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("bitrate \"fast\" is not a bitrate"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace cnc::can
