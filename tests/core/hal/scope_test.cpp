// The scope's capture buffer and trigger (core/hal/scope.cpp), alone and
// through halcmd's `scope` command.
#include <gtest/gtest.h>

#include "core/hal/commands.hpp"
#include "core/hal/scope.hpp"
#include "core/util/strings.hpp"
#include "tests/support/testing.hpp"

using namespace cnc::hal;
using State = ScopeCapture::State;

namespace {
std::vector<double> column(const std::vector<std::vector<double>>& rows, int c) {
  std::vector<double> out;
  for (const auto& r : rows) out.push_back(r[static_cast<std::size_t>(c)]);
  return out;
}
}  // namespace

TEST(ScopeCapture, RisingTriggerKeepsThePreTriggerShareBeforeIt) {
  ScopeCapture cap(100, 1);
  cap.configure(2, 8, 25, 0, ScopeEdge::Rising, 10.5, ScopeMode::Single);
  cap.arm();
  for (int i = 0; i < 40 && cap.state() != State::Done; ++i) {
    const double v[2] = {static_cast<double>(i), -static_cast<double>(i)};
    cap.push(v);
  }
  ASSERT_EQ(cap.state(), State::Done);
  EXPECT_EQ(cap.pre_samples(), 2u);
  const auto rows = cap.rows();
  EXPECT_EQ(column(rows, 0), (std::vector<double>{9, 10, 11, 12, 13, 14, 15, 16}));
  EXPECT_EQ(column(rows, 1)[2], -11.0) << "every channel of the trigger row";
  EXPECT_FALSE(cap.forced());
}

TEST(ScopeCapture, FallingTriggerAndNoTriggerDuringTheFill) {
  ScopeCapture cap(100, 1);
  // Falls through 0.5 at sample 2, during the pre-trigger fill: not a trigger.
  cap.configure(1, 4, 50, 0, ScopeEdge::Falling, 0.5, ScopeMode::Single);
  cap.arm();
  const double seq[] = {1, 1, 0, 0, 1, 1, 0, 0, 0, 0};
  for (double v : seq) cap.push(&v);
  ASSERT_EQ(cap.state(), State::Done);
  EXPECT_EQ(column(cap.rows(), 0), (std::vector<double>{1, 1, 0, 0}));
}

TEST(ScopeCapture, SingleWaitsForeverAutoFiresAfterABufferOfWaiting) {
  for (ScopeMode mode : {ScopeMode::Single, ScopeMode::Auto}) {
    ScopeCapture cap(100, 1);
    cap.configure(1, 10, 0, 0, ScopeEdge::Rising, 5, mode);
    cap.arm();
    for (int i = 0; i < 15; ++i) {
      const double v = 0;
      cap.push(&v);
    }
    if (mode == ScopeMode::Single) {
      EXPECT_EQ(cap.state(), State::Waiting);
    } else {
      EXPECT_EQ(cap.state(), State::Post);
      EXPECT_TRUE(cap.forced());
    }
  }
}

TEST(ScopeCapture, NothingIsWrittenWhileIdleOrDone) {
  ScopeCapture cap(10, 1);
  cap.configure(1, 2, 0, 0, ScopeEdge::None, 0, ScopeMode::Single);
  double v = 1;
  cap.push(&v);
  EXPECT_EQ(cap.state(), State::Idle);
  cap.arm();
  cap.push(&v);
  v = 2;
  cap.push(&v);
  ASSERT_EQ(cap.state(), State::Done);
  v = 3;
  cap.push(&v);
  EXPECT_EQ(column(cap.rows(), 0), (std::vector<double>{1, 2}));
  EXPECT_THROW(cap.configure(1, 11, 0, 0, ScopeEdge::None, 0, ScopeMode::Single), HalError) << "beyond the buffer";
}

TEST(Scope, HalcmdCapturesPinsToCsvWithoutAllocatingInTheCycle) {
  Hal hal;
  ComponentRegistry reg;
  register_core_components(reg);
  CommandInterpreter interp(hal, reg, nullptr, nullptr);
  interp.run_text(
      "loadrt threads name1=t period1=1000000\nloadrt scope samples=50\nloadrt siggen\n"
      "setp siggen.0.frequency 100\naddf siggen.0.update t\naddf scope.sample t\n",
      "t.hal");
  EXPECT_THROW(interp.execute("scope arm"), HalError) << "setup first";
  interp.execute("scope setup siggen.0.sine,siggen.0.clock trigger=siggen.0.clock edge=falling pre=20 samples=20");
  interp.execute("scope arm");
  EXPECT_THROW(interp.execute("scope csv"), HalError) << "nothing captured yet";
  cnc::rt::CycleInfo info;
  info.period_ns = info.actual_period_ns = 1'000'000;
  Thread* t = hal.find_thread("t");
  {
    cnc::testing::ScopedAllocationCheck check;
    for (int i = 0; i < 100; ++i) t->run_cycle(info);
    if (cnc::testing::AllocationCounter::available()) {
      EXPECT_EQ(check.allocations(), 0u);
    }
  }
  EXPECT_EQ(interp.execute("scope state"), "done samples=20 pre=4 channels=2\n");
  const std::string csv = interp.execute("scope csv");
  const auto lines = cnc::split(csv, '\n', true);
  ASSERT_EQ(lines.size(), 21u);
  EXPECT_EQ(lines[0], "time_s,siggen.0.sine,siggen.0.clock");
  EXPECT_EQ(lines[4].substr(0, 9), "-0.001000");
  EXPECT_EQ(lines[5].substr(0, 8), "0.000000");
  EXPECT_EQ(lines[4].back(), '1') << "the clock was high before the trigger";
  EXPECT_EQ(lines[5].back(), '0') << "and low at it";
}
