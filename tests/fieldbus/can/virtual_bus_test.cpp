#include <gtest/gtest.h>

#include <thread>
#include <vector>

#include "sim/can/virtual_bus.hpp"
#include "tests/support/testing.hpp"

using namespace cnc::can;

namespace {

std::vector<Frame> drain(Transport& t) {
  std::vector<Frame> out;
  Frame f;
  while (t.receive(f)) out.push_back(f);
  return out;
}

std::vector<Frame> data_frames(const std::vector<Frame>& v) {
  std::vector<Frame> out;
  for (const auto& f : v) {
    if (!f.is_error()) out.push_back(f);
  }
  return out;
}

struct Bus {
  explicit Bus(VirtualBusOptions o = {}) : bus(VirtualBus::create(o)), a(bus->open_port("a")), b(bus->open_port("b")),
                                           c(bus->open_port("c")) {}
  std::shared_ptr<VirtualBus> bus;
  std::unique_ptr<VirtualPort> a, b, c;
};

}  // namespace

TEST(VirtualBus, OpensThroughOpenTransportOnceRegistered) {
  register_virtual_transport();
  EXPECT_THROW(open_transport("virtual:x,bitrate=0"), std::runtime_error);
  EXPECT_THROW(open_transport("virtual:x,speed=1"), std::runtime_error);
  auto t = open_transport("virtual:open-transport-test,bitrate=500000");
  EXPECT_EQ(t->bitrate(), 500000u);
  EXPECT_EQ(t->name(), "virtual:port");
}

TEST(VirtualBus, DeliversToEveryOtherPortAfterTheFrameTime) {
  Bus t;
  ASSERT_EQ(t.a->send(Frame::make(0x181, {1, 2, 3, 4, 5, 6})), SendStatus::Ok);
  Frame f;
  EXPECT_FALSE(t.b->receive(f)) << "nothing arrives before time passes";
  t.bus->advance(114'000);
  EXPECT_FALSE(t.b->receive(f)) << "a 6-byte frame takes 115 us at 1 Mbit/s worst case";
  t.bus->advance(1'000);
  ASSERT_TRUE(t.b->receive(f));
  EXPECT_EQ(f.id, 0x181u);
  EXPECT_EQ(f.len, 6);
  EXPECT_EQ(f.timestamp_ns, 115'000);
  ASSERT_TRUE(t.c->receive(f));
  EXPECT_FALSE(t.a->receive(f)) << "the sender does not hear itself by default";
  t.a->set_receive_own(true);
  t.a->send(Frame::make(0x100, {}));
  t.bus->advance(1'000'000);
  EXPECT_TRUE(t.a->receive(f));
}

TEST(VirtualBus, ArbitrationLetsTheLowestIdentifierGoFirst) {
  Bus t;
  t.a->send(Frame::make(0x701, {0x05}));  // heartbeat
  t.b->send(Frame::make(0x181, {1}));     // TPDO
  t.c->send(Frame::make(0x080, {}));      // SYNC
  t.bus->advance(1'000'000);
  std::vector<uint32_t> seen_by_a;
  for (const auto& f : drain(*t.a)) seen_by_a.push_back(f.id);
  EXPECT_EQ(seen_by_a, (std::vector<uint32_t>{0x080, 0x181}));
  const auto at_b = drain(*t.b);
  ASSERT_EQ(at_b.size(), 2u);
  EXPECT_EQ(at_b[0].id, 0x080u);
  EXPECT_EQ(at_b[1].id, 0x701u);
  EXPECT_EQ(at_b[0].timestamp_ns, 55'000);
  EXPECT_EQ(at_b[1].timestamp_ns, 55'000 + 65'000 + 65'000) << "SYNC, then TPDO 0x181, then the heartbeat";
  EXPECT_EQ(t.bus->stats().arbitration_losses, 2u + 1u);
}

// A controller with one transmit queue sends in the order queued: a TPDO
// queued after the node's own event PDO waits for it, although it would
// win arbitration. With mailboxes (Priority) it goes first.
TEST(VirtualBus, AFifoControllerSendsInQueueOrderAPriorityOneByIdentifier) {
  for (const auto order : {VirtualPort::TxOrder::Fifo, VirtualPort::TxOrder::Priority}) {
    Bus t;
    t.b->set_tx_order(order);
    t.b->send(Frame::make(0x481, {1, 2, 3, 4, 5, 6, 7, 8}));  // event TPDO4, queued first
    t.b->send(Frame::make(0x381, {1, 2, 3, 4, 5, 6, 7, 8}));  // event TPDO3
    t.b->send(Frame::make(0x181, {1}));                     // TPDO1 answering SYNC
    t.bus->advance(1'000'000);
    std::vector<uint32_t> seen;
    for (const auto& f : drain(*t.a)) seen.push_back(f.id);
    if (order == VirtualPort::TxOrder::Fifo) {
      EXPECT_EQ(seen, (std::vector<uint32_t>{0x481, 0x381, 0x181}));
    } else {
      EXPECT_EQ(seen, (std::vector<uint32_t>{0x181, 0x381, 0x481}));
    }
  }
}

// Mailboxes choose among the frames queued by the time the bus is free: a
// higher-priority frame queued later does not hold back an earlier one
// that could already go.
TEST(VirtualBus, APriorityControllerSendsWhatIsQueuedWhenTheBusFrees) {
  Bus t;
  t.b->set_tx_order(VirtualPort::TxOrder::Priority);
  t.b->send(Frame::make(0x381, {1}));
  t.bus->advance(10'000);  // 0x381 on the wire
  t.b->send(Frame::make(0x182, {1}));
  t.b->send(Frame::make(0x281, {1}));
  t.bus->advance(1'000'000);
  std::vector<uint32_t> seen;
  for (const auto& f : drain(*t.a)) seen.push_back(f.id);
  EXPECT_EQ(seen, (std::vector<uint32_t>{0x381, 0x182, 0x281}));
}

TEST(VirtualBus, StandardBeatsExtendedAndDataBeatsRemoteWithTheSameBase) {
  Bus t;
  Frame ext;
  ext.flags = kExtended;
  ext.id = 0x123u << 18;
  t.a->send(ext);
  t.b->send(Frame::remote(0x123, 0));
  t.c->send(Frame::make(0x123, {}));
  t.bus->advance(1'000'000);
  auto all = drain(*t.a);  // a hears b's and c's
  ASSERT_EQ(all.size(), 2u);
  EXPECT_FALSE(all[0].is_remote()) << "data frame first";
  EXPECT_TRUE(all[1].is_remote());
  auto at_c = drain(*t.c);
  ASSERT_EQ(at_c.size(), 2u);
  EXPECT_TRUE(at_c[0].is_remote());
  EXPECT_TRUE(at_c[1].is_extended()) << "the extended frame loses against both";
}

TEST(VirtualBus, AFrameInFlightIsNotPreempted) {
  Bus t;
  t.a->send(Frame::make(0x700, {0}));
  t.bus->advance(10'000);  // 0x700 is on the wire now
  t.b->send(Frame::make(0x080, {}));
  t.bus->advance(1'000'000);
  const auto at_c = drain(*t.c);
  ASSERT_EQ(at_c.size(), 2u);
  EXPECT_EQ(at_c[0].id, 0x700u);
  EXPECT_EQ(at_c[1].timestamp_ns, 65'000 + 55'000);
}

TEST(VirtualBus, LoadAccountingUsesTheStuffingModel) {
  for (Stuffing s : {Stuffing::Nominal, Stuffing::WorstCase, Stuffing::Exact}) {
    VirtualBusOptions o;
    o.stuffing = s;
    o.bitrate = 500'000;
    Bus t(o);
    uint64_t expect_bits = 0;
    for (int cycle = 0; cycle < 100; ++cycle) {
      const Frame sync = Frame::make(0x080, {});
      const Frame pdo = Frame::make(0x201, {static_cast<uint8_t>(cycle), 0, 0, 0, 0x10, 0x27});
      t.a->send(sync);
      t.a->send(pdo);
      expect_bits += frame_bits(sync, s) + frame_bits(pdo, s);
      t.bus->advance(1'000'000);
    }
    const VirtualBusStats st = t.bus->stats();
    EXPECT_EQ(st.frames, 200u);
    EXPECT_EQ(st.bits, expect_bits) << to_string(s);
    EXPECT_EQ(st.busy_ns, static_cast<int64_t>(expect_bits) * 2'000);
    EXPECT_EQ(st.elapsed_ns, 100'000'000);
    EXPECT_NEAR(st.load(), static_cast<double>(expect_bits) * 2e-6 / 0.1, 1e-12);
  }
}

TEST(VirtualBus, FiltersSelectWhatAPortReceives) {
  Bus t;
  const Filter only_tpdo1[] = {Filter::range_mask(0x180, 0x780)};
  t.b->set_filters(only_tpdo1);
  t.a->send(Frame::make(0x185, {}));
  t.a->send(Frame::make(0x285, {}));
  t.bus->advance(1'000'000);
  const auto at_b = drain(*t.b);
  ASSERT_EQ(at_b.size(), 1u);
  EXPECT_EQ(at_b[0].id, 0x185u);
  EXPECT_EQ(drain(*t.c).size(), 2u);
  t.b->set_filters({});
  t.a->send(Frame::make(0x285, {}));
  t.bus->advance(1'000'000);
  EXPECT_EQ(drain(*t.b).size(), 1u);
}

TEST(VirtualBus, DroppedFramesVanishForAllOrOneReceiver) {
  Bus t;
  t.bus->drop_next(Filter::exact(0x181), 1);
  t.bus->drop_next(Filter::exact(0x182), 2, t.b.get());
  t.a->send(Frame::make(0x181, {}));
  t.a->send(Frame::make(0x181, {}));
  t.a->send(Frame::make(0x182, {}));
  t.bus->advance(1'000'000);
  const auto at_b = drain(*t.b);
  ASSERT_EQ(at_b.size(), 1u);
  EXPECT_EQ(at_b[0].id, 0x181u);
  EXPECT_EQ(drain(*t.c).size(), 2u) << "c still hears the second 0x181 and 0x182";
  EXPECT_EQ(t.bus->stats().dropped, 2u);
}

TEST(VirtualBus, CorruptedFramesAreRetransmittedAndCounted) {
  Bus t;
  t.bus->corrupt_next(Filter::exact(0x201), 2);
  t.a->send(Frame::make(0x201, {1, 2}));
  t.bus->advance(1'000'000);
  const auto at_b = drain(*t.b);
  const auto data = data_frames(at_b);
  ASSERT_EQ(data.size(), 1u) << "delivered once, after two failed attempts";
  EXPECT_EQ(at_b.size(), 3u) << "two error reports, then the frame";
  EXPECT_TRUE(at_b[0].is_error());
  EXPECT_EQ(data[0].timestamp_ns, 3 * 75'000 + 2 * static_cast<int64_t>(kErrorFrameBits) * 1'000);
  EXPECT_EQ(t.a->tx_error_counter(), 16u - 1u) << "+8 per error, -1 for the success";
  EXPECT_EQ(t.b->rx_error_counter(), 1u) << "+1 per error, -1 for the good reception";
  const auto at_a = drain(*t.a);
  ASSERT_EQ(at_a.size(), 2u);
  EXPECT_TRUE(decode_error_frame(at_a[0]).protocol & kProtTx);
  EXPECT_EQ(t.bus->stats().error_frames, 2u);
}

TEST(VirtualBus, RepeatedErrorsMakeATransmitterPassiveThenBusOff) {
  Bus t;
  t.bus->corrupt_next(Filter::exact(0x201), 32);
  t.a->send(Frame::make(0x201, {}));
  t.bus->advance(10'000'000);
  std::vector<BusState> seen;
  BusStateTracker tracker;
  for (const auto& f : drain(*t.a)) {
    if (tracker.on_error_frame(f)) seen.push_back(tracker.state());
  }
  EXPECT_EQ(seen, (std::vector<BusState>{BusState::ErrorWarning, BusState::ErrorPassive, BusState::BusOff}));
  EXPECT_EQ(t.a->state(), BusState::BusOff);
  EXPECT_EQ(t.a->send(Frame::make(0x201, {})), SendStatus::BusOff);
  EXPECT_TRUE(data_frames(drain(*t.b)).empty()) << "the frame never got through";
}

TEST(VirtualBus, BusOffRecoversAfterRestartAnd128x11RecessiveBits) {
  Bus t;
  t.bus->force_bus_off(*t.a);
  EXPECT_EQ(t.a->state(), BusState::BusOff);
  t.bus->advance(10'000'000);
  EXPECT_EQ(t.a->state(), BusState::BusOff) << "no automatic recovery unless configured";
  t.a->restart();
  t.bus->advance(static_cast<int64_t>(kBusOffRecoveryBits) * 1'000 - 1'000);
  EXPECT_EQ(t.a->state(), BusState::BusOff);
  t.bus->advance(1'000);
  EXPECT_EQ(t.a->state(), BusState::ErrorActive);
  EXPECT_EQ(t.a->tx_error_counter(), 0u);
  const auto reports = drain(*t.a);
  ASSERT_EQ(reports.size(), 2u);
  EXPECT_TRUE(decode_error_frame(reports[0]).classes & kErrBusOff);
  EXPECT_TRUE(decode_error_frame(reports[1]).classes & kErrRestarted);
  EXPECT_EQ(t.a->send(Frame::make(0x181, {})), SendStatus::Ok);
  t.bus->advance(1'000'000);
  EXPECT_EQ(data_frames(drain(*t.b)).size(), 1u);
}

TEST(VirtualBus, AutomaticBusOffRecovery) {
  VirtualBusOptions o;
  o.auto_restart_ns = 100'000'000;
  Bus t(o);
  t.bus->force_bus_off(*t.b);
  t.bus->advance(100'000'000);
  EXPECT_EQ(t.b->state(), BusState::BusOff);
  t.bus->advance(static_cast<int64_t>(kBusOffRecoveryBits) * 1'000);
  EXPECT_EQ(t.b->state(), BusState::ErrorActive);
}

TEST(VirtualBus, NoiseRaisesReceiveErrorCounters) {
  Bus t;
  t.bus->inject_error_frames(100);
  t.bus->advance(10'000'000);
  EXPECT_EQ(t.a->rx_error_counter(), 100u);
  EXPECT_EQ(t.a->state(), BusState::ErrorWarning);
  EXPECT_EQ(t.bus->stats().error_frames, 100u);
  t.bus->inject_error_frames(30);
  t.bus->advance(10'000'000);
  EXPECT_EQ(t.c->state(), BusState::ErrorPassive);
  // Good receptions bring a passive receiver back (RX counter to 119, then down).
  for (int i = 0; i < 30; ++i) t.a->send(Frame::make(0x181, {}));
  t.bus->advance(10'000'000);
  EXPECT_EQ(t.c->rx_error_counter(), 119u - 29u);
  EXPECT_EQ(t.c->state(), BusState::ErrorActive);
}

TEST(VirtualBus, FullQueuesRefuseWithoutBlocking) {
  Bus t;
  int ok = 0;
  while (t.a->send(Frame::make(0x300, {})) == SendStatus::Ok) ++ok;
  EXPECT_EQ(ok, static_cast<int>(VirtualBus::kQueueDepth));
  EXPECT_EQ(t.a->send(Frame::make(0x300, {})), SendStatus::WouldBlock);
  // b never reads: its receive queue overflows and the bus counts it.
  for (int i = 0; i < 4; ++i) t.bus->advance(100'000'000);
  while (t.a->send(Frame::make(0x300, {})) == SendStatus::Ok) {}
  for (int i = 0; i < 4; ++i) t.bus->advance(100'000'000);
  EXPECT_GT(t.b->stats().rx_overruns, 0u);
  EXPECT_EQ(t.b->stats().rx_frames, VirtualBus::kQueueDepth);
}

TEST(VirtualBus, SendAndReceiveDoNotAllocate) {
  Bus t;
  Frame f;
  {
    cnc::testing::ScopedAllocationCheck check;
    for (int i = 0; i < 1000; ++i) {
      t.a->send(Frame::make(0x181, {1, 2, 3}));
      t.bus->advance(200'000);
      while (t.b->receive(f)) {}
      while (t.c->receive(f)) {}
    }
    if (cnc::testing::AllocationCounter::available()) {
      EXPECT_EQ(check.allocations(), 0u);
    }
  }
}

TEST(VirtualBus, RealTimeClockDeliversAcrossThreads) {
  VirtualBusOptions o;
  o.manual_clock = false;
  auto bus = VirtualBus::create(o);
  auto a = bus->open_port("a");
  auto b = bus->open_port("b");
  std::thread echo([&] {
    Frame f;
    for (int n = 0; n < 50;) {
      if (!b->wait(2'000'000'000)) return;
      while (b->receive(f)) {
        f.id = 0x580 + (f.id & 0x7F);
        b->send(f);
        ++n;
      }
    }
  });
  int answered = 0;
  for (int i = 0; i < 50; ++i) {
    ASSERT_EQ(a->send(Frame::make(0x605, {static_cast<uint8_t>(i)})), SendStatus::Ok);
    Frame f;
    bool got = false;
    while (!got && a->wait(2'000'000'000)) got = a->receive(f);
    ASSERT_TRUE(got) << "reply " << i;
    EXPECT_EQ(f.id, 0x585u);
    EXPECT_EQ(f.data[0], i);
    ++answered;
  }
  echo.join();
  EXPECT_EQ(answered, 50);
  EXPECT_EQ(bus->stats().frames, 100u);
}
