#include <gtest/gtest.h>

#include <thread>
#include <vector>

#include "core/util/mpmc_ring.hpp"

namespace {
struct Item {
  uint32_t producer;
  uint32_t seq;
};
}  // namespace

TEST(MpmcRing, FullAndEmptyAreReported) {
  cnc::MpmcRing<int, 4> ring;
  int v = 0;
  EXPECT_FALSE(ring.pop(v));
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(ring.push(i));
  EXPECT_FALSE(ring.push(99));
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(ring.pop(v));
    EXPECT_EQ(v, i);
  }
  EXPECT_FALSE(ring.pop(v));
}

TEST(MpmcRing, ManyProducersNoLossAndOrderPerProducer) {
  constexpr uint32_t kProducers = 4, kPerProducer = 50000;
  cnc::MpmcRing<Item, 64> ring;
  std::vector<std::thread> producers;
  for (uint32_t p = 0; p < kProducers; ++p) {
    producers.emplace_back([&, p] {
      for (uint32_t i = 0; i < kPerProducer;) {
        if (ring.push(Item{p, i})) ++i;
        else std::this_thread::yield();
      }
    });
  }
  std::vector<uint32_t> next(kProducers, 0);
  uint32_t received = 0, out_of_order = 0;
  while (received < kProducers * kPerProducer) {
    Item it;
    if (!ring.pop(it)) { std::this_thread::yield(); continue; }
    if (it.seq != next[it.producer]) ++out_of_order;
    next[it.producer] = it.seq + 1;
    ++received;
  }
  for (auto& t : producers) t.join();
  EXPECT_EQ(out_of_order, 0u);
  for (uint32_t p = 0; p < kProducers; ++p) EXPECT_EQ(next[p], kPerProducer);
}
