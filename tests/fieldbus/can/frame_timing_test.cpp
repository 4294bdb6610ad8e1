#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "fieldbus/can/bus_load.hpp"
#include "fieldbus/can/frame_timing.hpp"

using namespace cnc::can;

TEST(FrameTiming, NominalAndWorstCaseMatchTheReferenceTable) {
  // canopen.md section 8: 11-bit identifier, n data bytes.
  const uint32_t n[] = {0, 1, 2, 4, 6, 7, 8};
  const uint32_t nominal[] = {47, 55, 63, 79, 95, 103, 111};
  const uint32_t worst[] = {55, 65, 75, 95, 115, 125, 135};
  for (int i = 0; i < 7; ++i) {
    EXPECT_EQ(nominal_frame_bits(false, n[i]), nominal[i]) << n[i] << " bytes";
    EXPECT_EQ(worst_case_frame_bits(false, n[i]), worst[i]) << n[i] << " bytes";
  }
  EXPECT_EQ(nominal_frame_bits(true, 8), 67u + 64u);
  EXPECT_EQ(worst_case_frame_bits(true, 8), 67u + 64u + (54u + 64u - 1u) / 4u);
}

TEST(FrameTiming, ExactStuffingOfAnAllZeroFrame) {
  // SOF, identifier 0, RTR, IDE, r0, DLC 0 and CRC 0 are 34 dominant bits:
  // a stuff bit after every fifth, 6 in all.
  const Frame f = Frame::make(0x000, {});
  EXPECT_EQ(frame_crc15(f), 0);
  EXPECT_EQ(stuff_bits(f), 6u);
  EXPECT_EQ(exact_frame_bits(f), 53u);
}

TEST(FrameTiming, Crc15OfAKnownFrame) {
  // Independent bitwise computation: polynomial division of the bit stream
  // (SOF..data) followed by 15 zero bits by x^15+x^14+x^10+x^8+x^7+x^4+x^3+1.
  const Frame f = Frame::make(0x123, {0xAA, 0x55});
  std::vector<int> bits;
  auto put = [&](uint32_t v, int n) { for (int i = n - 1; i >= 0; --i) bits.push_back((v >> i) & 1); };
  put(0, 1); put(0x123, 11); put(0, 1); put(0, 1); put(0, 1); put(2, 4); put(0xAA, 8); put(0x55, 8);
  for (int i = 0; i < 15; ++i) bits.push_back(0);
  const int poly[16] = {1, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1};  // x^15 .. x^0
  for (std::size_t i = 0; i + 15 < bits.size(); ++i) {
    if (bits[i]) for (int k = 0; k < 16; ++k) bits[i + k] ^= poly[k];
  }
  uint16_t crc = 0;
  for (std::size_t i = bits.size() - 15; i < bits.size(); ++i) crc = static_cast<uint16_t>((crc << 1) | bits[i]);
  EXPECT_EQ(frame_crc15(f), crc);
}

TEST(FrameTiming, ExactLiesBetweenNominalAndWorstCaseForRandomFrames) {
  const unsigned seed = 20240601;
  std::mt19937 rng(seed);
  for (int i = 0; i < 20000; ++i) {
    Frame f;
    const bool ext = (rng() & 3) == 0;
    f.flags = ext ? kExtended : 0;
    f.id = ext ? (rng() & kExtendedIdMask) : (rng() & kStandardIdMask);
    f.len = static_cast<uint8_t>(rng() % 9);
    for (auto& b : f.data) b = static_cast<uint8_t>(rng());
    if ((rng() & 7) == 0) f.data.fill(static_cast<uint8_t>((rng() & 1) ? 0xFF : 0x00));
    const uint32_t exact = exact_frame_bits(f);
    ASSERT_GE(exact, nominal_frame_bits(ext, f.len)) << "seed " << seed << " frame " << i;
    ASSERT_LE(exact, worst_case_frame_bits(ext, f.len)) << "seed " << seed << " frame " << i;
  }
}

namespace {
double round1(double v) { return std::round(v * 10.0) / 10.0; }
}

TEST(BusLoad, CapacityTableOfTheReference) {
  // canopen.md section 8: CSP axes per 1 Mbit/s bus, nominal / worst case.
  struct Row {
    std::vector<uint32_t> rpdo, tpdo;
    uint32_t nominal_bits, worst_bits;
    double cells[8];  // 1 kHz 100 %, 1 kHz 80 %, 500 Hz 100 %, 500 Hz 80 %; nominal/worst each
  };
  const Row rows[] = {
      {{6}, {6}, 190, 230, {5.0, 4.1, 4.0, 3.2, 10.3, 8.5, 8.2, 6.7}},
      {{7}, {7}, 206, 250, {4.6, 3.8, 3.7, 3.0, 9.5, 7.8, 7.5, 6.2}},
      {{8}, {8}, 222, 270, {4.3, 3.5, 3.4, 2.8, 8.8, 7.2, 7.0, 5.7}},
      {{6}, {8, 8}, 317, 385, {3.0, 2.5, 2.4, 1.9, 6.2, 5.1, 4.9, 4.0}},
  };
  const uint32_t sync_nominal = nominal_frame_bits(false, 0), sync_worst = worst_case_frame_bits(false, 0);
  for (const auto& r : rows) {
    const AxisBits b = axis_bits(r.rpdo, r.tpdo);
    EXPECT_EQ(b.nominal, r.nominal_bits);
    EXPECT_EQ(b.worst_case, r.worst_bits);
    int c = 0;
    for (int64_t cycle : {1'000'000, 2'000'000}) {
      for (double budget : {1.0, 0.8}) {
        EXPECT_DOUBLE_EQ(round1(axes_per_bus(b.nominal, sync_nominal, cycle, 1'000'000, budget)), r.cells[c])
            << r.nominal_bits << " bits, cycle " << cycle << ", budget " << budget;
        EXPECT_DOUBLE_EQ(round1(axes_per_bus(b.worst_case, sync_worst, cycle, 1'000'000, budget)), r.cells[c + 1])
            << r.worst_bits << " bits, cycle " << cycle << ", budget " << budget;
        c += 2;
      }
    }
  }
}

TEST(BusLoad, ScheduleWithDividersAndPeriodicFrames) {
  std::vector<ScheduledFrame> plan = {
      {"SYNC", 0, false, 1, 0},
      {"RPDO1", 6, false, 1, 0},
      {"TPDO1", 6, false, 1, 0},
      {"TPDO2", 8, false, 4, 0},              // every 4th SYNC
      {"heartbeat", 1, false, 1, 100'000'000}, // every 100 ms
  };
  const BusLoad l = compute_bus_load(plan, 1'000'000, 1'000'000);
  EXPECT_DOUBLE_EQ(l.cycle_bits, 1000.0);
  EXPECT_DOUBLE_EQ(l.nominal_bits_per_cycle, 47 + 95 + 95 + 111 / 4.0 + 55 / 100.0);
  EXPECT_DOUBLE_EQ(l.worst_bits_per_cycle, 55 + 115 + 115 + 135 / 4.0 + 65 / 100.0);
  EXPECT_NEAR(l.worst_case(), (55 + 115 + 115 + 135 / 4.0 + 0.65) / 1000.0, 1e-12);
  const BusLoad slow = compute_bus_load(plan, 1'000'000, 500'000);
  EXPECT_NEAR(slow.worst_case(), 2 * l.worst_case(), 1e-12);
}

// The 47 bits of a standard frame without data already end with the 3-bit
// intermission (SOF 1, identifier 11, RTR, IDE, r0, DLC 4, CRC 15, CRC
// delimiter, ACK 2, EOF 7 = 44, + 3): a plan adds nothing per frame.
TEST(BusLoad, AFrameCountsItsIntermissionOnce) {
  EXPECT_EQ(nominal_frame_bits(false, 0), 1u + 11 + 1 + 1 + 1 + 4 + 15 + 1 + 2 + 7 + 3);
  EXPECT_EQ(worst_case_frame_bits(false, 8), 111u + (34 + 64 - 1) / 4);
  const BusLoad l = compute_bus_load({{"SYNC", 0, false, 1, 0}}, 1'000'000, 1'000'000);
  EXPECT_DOUBLE_EQ(l.worst_bits_per_cycle, 55);
  ASSERT_EQ(l.slots.size(), 1u);
  EXPECT_DOUBLE_EQ(l.slots[0].total(), 55);
}

namespace {
ScheduledFrame sync_frame(const char* label, uint32_t bytes, uint32_t cob, uint32_t every = 1, int32_t slot = -1) {
  ScheduledFrame f;
  f.label = label;
  f.data_bytes = bytes;
  f.cob_id = cob;
  f.every_n_cycles = every;
  f.slot = slot;
  return f;
}
ScheduledFrame sporadic(const char* label, uint32_t bytes, uint32_t cob, int64_t interval_ns) {
  ScheduledFrame f = sync_frame(label, bytes, cob);
  f.period_ns = interval_ns;
  return f;
}
}  // namespace

// Three TPDOs sent every 20th SYNC with no known phase all land in the
// planned cycle; with known phases each has its own slot.
TEST(BusLoad, DividedFramesWithoutAKnownPhaseCoincideInTheWorstSlot) {
  std::vector<ScheduledFrame> plan = {sync_frame("SYNC", 0, 0x80)};
  for (uint32_t n = 1; n <= 3; ++n) plan.push_back(sync_frame("TPDO4", 8, 0x480 + n, 20));
  BusLoad l = compute_bus_load(plan, 1'000'000, 1'000'000);
  ASSERT_EQ(l.slots.size(), 1u);
  EXPECT_DOUBLE_EQ(l.slots[0].synchronous_bits, 55 + 3 * 135);
  EXPECT_DOUBLE_EQ(l.worst_bits_per_cycle, 55 + 3 * 135 / 20.0);
  for (int32_t i = 0; i < 3; ++i) plan[static_cast<std::size_t>(i) + 1].slot = i * 7;
  l = compute_bus_load(plan, 1'000'000, 1'000'000);
  ASSERT_EQ(l.slots.size(), 20u);
  EXPECT_DOUBLE_EQ(l.slots[0].synchronous_bits, 55 + 135);
  EXPECT_DOUBLE_EQ(l.slots[7].synchronous_bits, 55 + 135);
  EXPECT_DOUBLE_EQ(l.slots[1].synchronous_bits, 55);
  EXPECT_DOUBLE_EQ(l.worst_cycle(), (55 + 135) / 1000.0);
}

// Sporadic frames and allowances with a higher priority than the slot's
// last synchronous frame count as often as they fit in a cycle; of the
// lower-priority ones only the longest counts, once (no pre-emption).
TEST(BusLoad, HigherPriorityEventsInterfereLowerPriorityOnesBlockOnce) {
  std::vector<ScheduledFrame> plan = {sync_frame("SYNC", 0, 0x80), sync_frame("RPDO1", 6, 0x201),
                                      sync_frame("TPDO1", 6, 0x181)};
  plan.push_back(sporadic("TPDO2 (inhibit 0.4 ms)", 4, 0x101, 400'000));  // above the RPDO: 3 per 1 ms
  plan.push_back(sporadic("TPDO3", 8, 0x381, 1'000'000));                 // below
  plan.push_back(sporadic("heartbeat", 1, 0x701, 100'000'000));           // below
  ScheduledFrame emcy = sync_frame("EMCY", 8, 0x81);
  emcy.per_cycle = 1;
  plan.push_back(emcy);
  const BusLoad l = compute_bus_load(plan, 1'000'000, 1'000'000);
  ASSERT_EQ(l.slots.size(), 1u);
  EXPECT_DOUBLE_EQ(l.slots[0].synchronous_bits, 55 + 2 * 115);
  EXPECT_DOUBLE_EQ(l.slots[0].interference_bits, 3 * 95 + 135);
  EXPECT_DOUBLE_EQ(l.slots[0].blocking_bits, 135);
  // Average: the event PDOs at their intervals, the allowance not.
  EXPECT_DOUBLE_EQ(l.worst_bits_per_cycle, 55 + 2 * 115 + 95 * 2.5 + 135 + 65 / 100.0);
}

// A node that sends in queue order (one FIFO) delays its synchronous TPDO
// behind its own event frames, whatever their identifiers: they count as
// interference, and so does every frame of others that outranks the
// node's lowest-priority frame. With priority-ordered mailboxes the same
// event frames block once at most.
TEST(BusLoad, AFifoNodesOwnEventFramesDelayItsSynchronousTpdo) {
  std::vector<ScheduledFrame> plan = {sync_frame("SYNC", 0, 0x80), sync_frame("RPDO1", 6, 0x201),
                                      sync_frame("TPDO1", 6, 0x181)};
  plan.push_back(sporadic("TPDO3", 8, 0x381, 10'000'000));
  plan.push_back(sporadic("TPDO4", 8, 0x481, 20'000'000));
  plan.push_back(sporadic("other node TPDO2", 8, 0x282, 10'000'000));
  const BusLoad mailboxes = compute_bus_load(plan, 1'000'000, 1'000'000);
  EXPECT_DOUBLE_EQ(mailboxes.slots[0].interference_bits, 0);
  EXPECT_DOUBLE_EQ(mailboxes.slots[0].blocking_bits, 135);
  for (std::size_t i : {2u, 3u, 4u}) plan[i].fifo_group = 1;  // the node's TPDO1, TPDO3, TPDO4
  const BusLoad fifo = compute_bus_load(plan, 1'000'000, 1'000'000);
  EXPECT_DOUBLE_EQ(fifo.slots[0].synchronous_bits, 55 + 2 * 115);
  // Its own TPDO3 and TPDO4, and the other node's 0x282 (it outranks 0x481).
  EXPECT_DOUBLE_EQ(fifo.slots[0].interference_bits, 3 * 135);
  EXPECT_DOUBLE_EQ(fifo.slots[0].blocking_bits, 0);
  EXPECT_GT(fifo.worst_cycle(), mailboxes.worst_cycle());
}
