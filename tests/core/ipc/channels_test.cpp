#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <map>
#include <thread>

#include "core/ipc/client.hpp"
#include "core/ipc/server.hpp"
#include "tests/support/testing.hpp"

using namespace cnc::ipc;

TEST(BroadcastRing, ReadersKeepTheirOwnPlace) {
  BroadcastRing<int, 8> ring;
  uint64_t a = ring.head(), b = ring.head();
  for (int i = 0; i < 5; ++i) ring.write(i);
  int v = 0;
  ASSERT_EQ(ring.read(a, v), (BroadcastRing<int, 8>::ReadResult::Ok));
  EXPECT_EQ(v, 0);
  ASSERT_EQ(ring.read(a, v), (BroadcastRing<int, 8>::ReadResult::Ok));
  EXPECT_EQ(v, 1);
  ASSERT_EQ(ring.read(b, v), (BroadcastRing<int, 8>::ReadResult::Ok));
  EXPECT_EQ(v, 0) << "a second reader starts from its own cursor";
}

TEST(BroadcastRing, ALappedReaderLearnsHowManyItLost) {
  BroadcastRing<int, 8> ring;
  uint64_t cur = 0;
  for (int i = 0; i < 20; ++i) ring.write(i);
  int v = 0;
  uint64_t lost = 0;
  EXPECT_EQ(ring.read(cur, v, &lost), (BroadcastRing<int, 8>::ReadResult::Lost));
  EXPECT_EQ(lost, 12u);
  ASSERT_EQ(ring.read(cur, v), (BroadcastRing<int, 8>::ReadResult::Ok));
  EXPECT_EQ(v, 12);
  for (int expect = 13; expect < 20; ++expect) {
    ASSERT_EQ(ring.read(cur, v), (BroadcastRing<int, 8>::ReadResult::Ok));
    EXPECT_EQ(v, expect);
  }
  EXPECT_EQ(ring.read(cur, v), (BroadcastRing<int, 8>::ReadResult::Empty));
}

TEST(CommandChannel, ManyClientProcessesNoLossAndOrderPerWriter) {
  constexpr int kWriters = 6, kPerWriter = 400;
  const auto inst = cnc::testing::unique_name("cmds");
  Server server(inst);
  server.set_ready(true);
  std::vector<pid_t> kids;
  for (int w = 0; w < kWriters; ++w) {
    const pid_t pid = ::fork();
    if (pid == 0) {
      Client c(inst);
      for (int i = 0; i < kPerWriter;) {
        Command cmd = make_command(CommandType::Ping);
        cmd.i[0] = w;
        cmd.i[1] = i;
        uint32_t serial = 0;
        if (c.try_send(cmd, serial)) ++i;
        else std::this_thread::yield();
      }
      ::_exit(0);
    }
    kids.push_back(pid);
  }
  std::map<int, int> next;
  std::map<int32_t, int> writer_of_pid;
  int received = 0, out_of_order = 0, mixed = 0;
  uint32_t last_serial_seen = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (received < kWriters * kPerWriter && std::chrono::steady_clock::now() < deadline) {
    Command cmd;
    if (!server.poll_command(cmd)) {
      std::this_thread::yield();
      continue;
    }
    ++received;
    if (cmd.i[1] != next[cmd.i[0]]) ++out_of_order;
    next[cmd.i[0]] = cmd.i[1] + 1;
    auto [it, inserted] = writer_of_pid.emplace(cmd.client_pid, cmd.i[0]);
    if (!inserted && it->second != cmd.i[0]) ++mixed;
    last_serial_seen = std::max(last_serial_seen, cmd.serial);
  }
  for (pid_t p : kids) ::waitpid(p, nullptr, 0);
  EXPECT_EQ(received, kWriters * kPerWriter);
  EXPECT_EQ(out_of_order, 0);
  EXPECT_EQ(mixed, 0);
  EXPECT_EQ(last_serial_seen, static_cast<uint32_t>(kWriters * kPerWriter)) << "serials are unique and dense";
}

TEST(CommandChannel, ResultsReachTheSenderWithReasons) {
  const auto inst = cnc::testing::unique_name("res");
  Server server(inst);
  server.set_ready(true);
  Client client(inst);
  std::atomic<bool> stop{false};
  std::thread controller([&] {
    while (!stop) {
      Command cmd;
      if (!server.poll_command(cmd)) {
        std::this_thread::sleep_for(std::chrono::microseconds(200));
        continue;
      }
      if (cmd.type == CommandType::Ping) {
        server.report(cmd, CommandState::Done);
      } else {
        server.report(cmd, CommandState::Executing);
        server.report(cmd, CommandState::Rejected, "machine is in E-stop");
      }
    }
  });
  const auto ok = client.execute(make_command(CommandType::Ping), std::chrono::seconds(5));
  EXPECT_EQ(ok.state, CommandState::Done);
  const auto bad = client.execute(make_command(CommandType::JointHome), std::chrono::seconds(5));
  EXPECT_EQ(bad.state, CommandState::Rejected);
  EXPECT_STREQ(bad.reason.c_str(), "machine is in E-stop");
  EXPECT_EQ(bad.type, CommandType::JointHome);
  stop = true;
  controller.join();
  // The status echoes the last serial received.
  server.publish(Status{});
  EXPECT_EQ(client.status().echo.serial, bad.serial);
  EXPECT_EQ(client.status().echo.state, CommandState::Rejected);
}

TEST(CommandChannel, QueueFullIsReportedNotLost) {
  const auto inst = cnc::testing::unique_name("full");
  Server server(inst);
  Client client(inst);
  for (std::size_t i = 0; i < kClientQueueDepth; ++i) client.send(make_command(CommandType::Ping));
  EXPECT_THROW(client.send(make_command(CommandType::Ping)), ClientError);
  int taken = 0;
  Command cmd;
  while (server.poll_command(cmd)) ++taken;
  EXPECT_EQ(taken, static_cast<int>(kClientQueueDepth));
}

TEST(MessageChannel, EveryReaderGetsEveryMessageInOrder) {
  const auto inst = cnc::testing::unique_name("msg");
  Server server(inst);
  Client a(inst), b(inst);
  for (int i = 0; i < 10; ++i) {
    cnc::Message m;
    m.kind = i % 2 ? cnc::MessageKind::Text : cnc::MessageKind::Error;
    m.source.assign("test");
    m.text.format("message %d", i);
    server.post(m);
  }
  for (Client* c : {&a, &b}) {
    cnc::Message m;
    for (int i = 0; i < 10; ++i) {
      ASSERT_TRUE(c->next_message(m));
      EXPECT_EQ(m.text.view(), "message " + std::to_string(i));
    }
    EXPECT_FALSE(c->next_message(m));
  }
}

TEST(MessageChannel, SlowReaderIsToldWhatItLost) {
  const auto inst = cnc::testing::unique_name("lost");
  Server server(inst);
  Client c(inst);
  for (int i = 0; i < 300; ++i) {
    cnc::Message m;
    m.text.format("%d", i);
    server.post(m);
  }
  cnc::Message m;
  uint64_t lost = 0;
  ASSERT_TRUE(c.next_message(m, &lost));
  EXPECT_EQ(lost, 300u - 256u);
  EXPECT_EQ(m.text.view(), "44");
}
