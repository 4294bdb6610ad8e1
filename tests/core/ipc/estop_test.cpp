// The segment's E-stop words: a request needs no command channel (all of
// them may be taken), concurrent requests are all counted, the requester
// waits for motion's acknowledgement, and clients judge how fresh the
// status and the servo heartbeat are.
#include <gtest/gtest.h>
#include <unistd.h>

#include <memory>
#include <thread>
#include <vector>

#include "core/ipc/client.hpp"
#include "core/ipc/server.hpp"
#include "tests/support/testing.hpp"

using namespace cnc::ipc;

TEST(EstopWord, ARequestNeedsNoChannelEvenWhenAllAreTaken) {
  const auto inst = cnc::testing::unique_name("estop");
  Server server(inst);
  server.set_ready(true);
  std::vector<std::unique_ptr<Client>> others;
  for (int i = 0; i < kMaxClients; ++i) {
    others.push_back(std::make_unique<Client>(inst));
    others.back()->send(make_command(CommandType::Ping));  // claims a channel
  }
  Client late(inst);
  uint32_t serial = 0;
  try {
    late.try_send(make_command(CommandType::Ping), serial);
    FAIL() << "a channel was still free";
  } catch (const ClientError& e) {
    EXPECT_NE(std::string(e.what()).find("too many clients"), std::string::npos) << e.what();
  }
  const uint64_t word = late.request_estop();
  EXPECT_EQ(estop_count(word), 1u);
  EXPECT_EQ(estop_pid(word), ::getpid());
  EXPECT_EQ(server.segment().header.estop.request.load(), word);
  EXPECT_FALSE(late.wait_estop_acknowledged(word, std::chrono::milliseconds(0))) << "motion has not acted yet";
  server.segment().header.estop.acknowledged.store(word);  // what motion writes once it has acted
  EXPECT_TRUE(late.wait_estop_acknowledged(word, std::chrono::milliseconds(0)));
  Command taken;
  while (server.poll_command(taken)) {
  }
}

TEST(EstopWord, ConcurrentRequestsAreAllCountedAndAnOlderAcknowledgementDoesNotCoverANewerRequest) {
  EstopWords w;
  constexpr int kThreads = 4, kEach = 5000;
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&w, t] {
      for (int i = 0; i < kEach; ++i) bump_estop_request(w, 100 + t);
    });
  }
  for (auto& t : threads) t.join();
  const uint64_t last = w.request.load();
  EXPECT_EQ(estop_count(last), static_cast<uint32_t>(kThreads * kEach));
  EXPECT_GE(estop_pid(last), 100);
  EXPECT_LT(estop_pid(last), 100 + kThreads);
  const uint64_t newer = bump_estop_request(w, 7);
  EXPECT_FALSE(estop_acknowledges(last, newer));
  EXPECT_TRUE(estop_acknowledges(newer, last));
  // Counts wrap: compared modulo 2^32.
  EXPECT_TRUE(estop_acknowledges(uint64_t{1} << 32, uint64_t{0xFFFFFFFFu} << 32));
}

TEST(Liveness, TheStatusIsStaleAfterHalfASecondOrTenTaskCyclesTheServoAfterAQuarterSecondOrAHundredPeriods) {
  const int64_t t = 1'000'000'000'000;
  // 1 ms task cycle: 0.5 s is the bound.
  EXPECT_FALSE(assess_liveness(t, t - 400'000'000, t - 1'000'000, 1'000'000, 0.001).task_stalled);
  EXPECT_TRUE(assess_liveness(t, t - 600'000'000, t - 1'000'000, 1'000'000, 0.001).task_stalled);
  // 0.1 s task cycle: ten cycles (1 s).
  EXPECT_FALSE(assess_liveness(t, t - 900'000'000, t, 100'000'000, 0.001).task_stalled);
  EXPECT_TRUE(assess_liveness(t, t - 1'100'000'000, t, 100'000'000, 0.001).task_stalled);
  // Servo: 0.25 s or 100 periods.
  const Liveness l = assess_liveness(t, t, t - 300'000'000, 1'000'000, 0.001);
  EXPECT_TRUE(l.servo_stalled);
  EXPECT_EQ(l.servo_age_ns, 300'000'000);
  EXPECT_FALSE(assess_liveness(t, t, t - 200'000'000, 1'000'000, 0.001).servo_stalled);
  EXPECT_FALSE(assess_liveness(t, t, t - 300'000'000, 1'000'000, 0.004).servo_stalled);
  // No motion: no servo heartbeat.
  const Liveness none = assess_liveness(t, t, 0, 1'000'000, 0.001);
  EXPECT_EQ(none.servo_age_ns, -1);
  EXPECT_FALSE(none.servo_stalled);
}
