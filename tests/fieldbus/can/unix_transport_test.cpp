// "unix:<path>": another process's bus, and the simulators' share of an
// in-process bus that offers it (sim/can/bus_share.hpp). Here both ends are
// in one process; tests/commission/cli_running_controller.sh does it
// across processes with cncd.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <string>
#include <thread>

#include "fieldbus/can/transport.hpp"
#include "fieldbus/can/unix_transport.hpp"
#include "sim/can/bus_share.hpp"
#include "sim/can/virtual_bus.hpp"

using namespace cnc::can;

namespace {

std::string temp_path(const std::string& what) {
  return (std::filesystem::temp_directory_path() /
          ("cnc-unix-can-" + what + "-" + std::to_string(::getpid())))
      .string();
}

// A listening SOCK_SEQPACKET socket at `path` (replacing a file there).
int listen_at(const std::string& path) {
  ::unlink(path.c_str());
  const int fd = ::socket(AF_UNIX, SOCK_SEQPACKET, 0);
  sockaddr_un a{};
  a.sun_family = AF_UNIX;
  std::strcpy(a.sun_path, path.c_str());
  EXPECT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)), 0) << path;
  EXPECT_EQ(::listen(fd, 4), 0) << path;
  return fd;
}

// Waits up to 2 s for a frame on `t`.
bool receive_within(Transport& t, Frame& f) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  while (std::chrono::steady_clock::now() < end) {
    if (t.receive(f)) return true;
    t.wait(10'000'000);
  }
  return false;
}

struct SharedBus : ::testing::Test {
  void SetUp() override {
    register_virtual_transport();
    path = temp_path(::testing::UnitTest::GetInstance()->current_test_info()->name());
    bus_name = "unix-test-" + std::to_string(::getpid()) + "-" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name();
    device = open_transport("virtual:" + bus_name + ",share=" + path);
  }
  std::string path, bus_name;
  std::unique_ptr<Transport> device;  // a controller on the owner's in-process bus
};

}  // namespace

TEST_F(SharedBus, AClientOnTheSocketIsOneMoreControllerOnTheBusBothWays) {
  auto client = open_transport("unix:" + path);
  EXPECT_EQ(client->name(), "unix:" + path);
  EXPECT_EQ(client->bitrate(), 1'000'000u);  // from the owner's greeting
  EXPECT_EQ(client->state(), BusState::ErrorActive);

  ASSERT_EQ(client->send(Frame::make(0x601, {0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0})), SendStatus::Ok);
  Frame f;
  ASSERT_TRUE(receive_within(*device, f)) << "the client's frame never reached the bus";
  EXPECT_EQ(f.id, 0x601u);
  EXPECT_EQ(f.len, 8);
  EXPECT_EQ(f.data[1], 0x18);

  ASSERT_EQ(device->send(Frame::make(0x581, {0x43, 0x18, 0x10, 0x01, 0xC1, 0x0C, 0, 0})), SendStatus::Ok);
  ASSERT_TRUE(receive_within(*client, f)) << "the bus's frame never reached the client";
  EXPECT_EQ(f.id, 0x581u);
  EXPECT_EQ(f.data[4], 0xC1);
  EXPECT_GT(f.timestamp_ns, 0);
  EXPECT_EQ(client->stats().tx_frames, 1u);
  EXPECT_EQ(client->stats().rx_frames, 1u);
}

TEST_F(SharedBus, TwoClientsSeeEachOthersFramesButNotTheirOwn) {
  auto a = open_transport("unix:" + path);
  auto b = open_transport("unix:" + path);
  ASSERT_EQ(a->send(Frame::make(0x123, {1, 2, 3})), SendStatus::Ok);
  Frame f;
  ASSERT_TRUE(receive_within(*b, f));
  EXPECT_EQ(f.id, 0x123u);
  ASSERT_TRUE(receive_within(*device, f));
  EXPECT_EQ(f.id, 0x123u);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_FALSE(a->receive(f)) << "a controller does not receive its own frames";
}

TEST_F(SharedBus, FiltersSelectWhatTheClientReceives) {
  auto client = open_transport("unix:" + path);
  const Filter only[] = {Filter::exact(0x585)};
  client->set_filters(only);
  ASSERT_EQ(device->send(Frame::make(0x581, {1})), SendStatus::Ok);
  ASSERT_EQ(device->send(Frame::make(0x585, {5})), SendStatus::Ok);
  Frame f;
  ASSERT_TRUE(receive_within(*client, f));
  EXPECT_EQ(f.id, 0x585u) << "0x581 passed the filter";
}

TEST_F(SharedBus, ASocketFileLeftByAnEndedProcessIsReplaced) {
  const std::string stale = path + "-stale";
  {  // a socket bound and closed without unlink: what a killed owner leaves
    const int fd = ::socket(AF_UNIX, SOCK_SEQPACKET, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::strcpy(a.sun_path, stale.c_str());
    ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)), 0);
    ::close(fd);
  }
  ASSERT_TRUE(std::filesystem::exists(stale));
  auto owner = open_transport("virtual:" + bus_name + "-2,share=" + stale);
  auto client = open_transport("unix:" + stale);
  ASSERT_EQ(owner->send(Frame::make(0x80, {})), SendStatus::Ok);
  Frame f;
  EXPECT_TRUE(receive_within(*client, f));
}

TEST_F(SharedBus, APathSomeoneElseListensOnIsLeftAloneWithAWarning) {
  // A live listener at the path (another controller of the same instance):
  // the new bus is not shared, the simulation runs on, stderr says why.
  const std::string p = path + "-taken";
  const int fd = listen_at(p);
  testing::internal::CaptureStderr();
  auto other = open_transport("virtual:" + bus_name + "-other,share=" + p);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("is not shared with other processes: " + p + " is offered by another process"), std::string::npos)
      << err;
  EXPECT_TRUE(std::filesystem::exists(p)) << "the other owner's socket was removed";
  ::close(fd);
  ::unlink(p.c_str());
}

TEST(UnixTransport, NothingListeningIsAnErrorNamingTheSpecAndWhatToStart) {
  try {
    open_transport("unix:/nonexistent/cnc-bus");
    FAIL() << "opened a bus nobody offers";
  } catch (const std::runtime_error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("\"unix:/nonexistent/cnc-bus\""), std::string::npos) << m;
    EXPECT_NE(m.find("nothing offers a bus at /nonexistent/cnc-bus"), std::string::npos) << m;
    EXPECT_NE(m.find("virtual:<bus>,share"), std::string::npos) << m;
  }
  EXPECT_THROW(open_transport("unix:/tmp/x,fd"), std::runtime_error);
  register_virtual_transport();
  EXPECT_THROW(open_transport("virtual:b,share="), std::runtime_error);
}

TEST(UnixTransport, ASocketThatIsNoBusIsRefused) {
  const std::string p = temp_path("nobus");
  const int fd = listen_at(p);
  std::thread greeter([&] {
    const int c = ::accept(fd, nullptr, nullptr);
    const char junk[16] = "HELLO";
    (void)::send(c, junk, sizeof(junk), 0);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    ::close(c);
  });
  try {
    open_transport("unix:" + p);
    ADD_FAILURE() << "accepted a socket that is no bus";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("other than a CAN bus greeting"), std::string::npos) << e.what();
  }
  greeter.join();
  ::close(fd);
  ::unlink(p.c_str());
}

TEST(UnixTransport, WhenTheOwnerGoesAwaySendSaysDown) {
  const std::string p = temp_path("owner-gone");
  const int fd = listen_at(p);
  int conn = -1;
  std::thread owner([&] {
    conn = ::accept(fd, nullptr, nullptr);
    UnixWireHello hello;
    hello.bitrate = 500'000;
    (void)::send(conn, &hello, sizeof(hello), 0);
  });
  auto client = open_transport("unix:" + p);
  owner.join();
  EXPECT_EQ(client->bitrate(), 500'000u);
  ::close(conn);
  ::close(fd);
  ::unlink(p.c_str());
  Frame f;
  EXPECT_FALSE(client->receive(f));
  EXPECT_EQ(client->state(), BusState::BusOff);
  EXPECT_EQ(client->send(Frame::make(0x1, {})), SendStatus::Down);
}
