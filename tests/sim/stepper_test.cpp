// cia402_sim on a servo-clocked virtual bus: a servo thread on its own
// clock only asks for the period and the component's stepper thread
// simulates it; a thread stepped by hand simulates it inline, exactly one
// period per cycle. Waits poll with generous limits; no timing is asserted.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "core/hal/commands.hpp"
#include "core/hal/component.hpp"
#include "core/hal/thread.hpp"
#include "core/ini/ini_file.hpp"
#include "core/ipc/service.hpp"
#include "core/ipc/status.hpp"
#include "core/util/messages.hpp"
#include "sim/can/virtual_bus.hpp"
#include "sim/register.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;

namespace {

class SimStepper : public ::testing::Test {
 protected:
  void SetUp() override {
    bus_name = cnc::testing::unique_name("stepper");
    ini = ini::IniFile::parse("[CIA402_SIM]\nINTERFACE = virtual:" + bus_name +
                                  "\nCLOCK = SERVO\nSTEPPER = THREAD\nNODE = 1\n[CIA402_SIM_NODE_1]\nNAME = x\nENCODER_COUNTS = 10000\n"
                                  "SCREW_LEAD = 5\n",
                              "sim.ini");
    hal::register_core_components(registry);
    sim::register_components(registry);
    halcmd = std::make_unique<hal::CommandInterpreter>(hal, registry, &ini, &messages);
    halcmd->run_text("loadrt threads name1=servo-thread period1=1000000\nloadrt cia402_sim\n"
                     "addf cia402-sim.0.update servo-thread\n",
                     "test.hal");
    thread = hal.find_thread("servo-thread");
    bus = can::VirtualBus::named(bus_name, {});
    for (hal::Component* c : hal.components()) {
      if (auto* s = dynamic_cast<ipc::ControllerService*>(c)) service = s;
    }
    info.period_ns = info.actual_period_ns = 1'000'000;
  }
  void TearDown() override { hal.clear(); }

  void cycle(bool periodic) {
    info.periodic = periodic;
    thread->run_cycle(info);
    ++info.cycle;
  }
  ipc::SimulatorStatus simulator() {
    auto s = std::make_unique<ipc::Status>();
    service->contribute_status(*s);
    return s->simulators[0];
  }
  // `cnc inject TEXT VALUE`: true when done.
  bool inject(const std::string& text, double value) {
    struct Reporter : ipc::CommandReporter {
      void report(const ipc::Command&, ipc::CommandState state, std::string_view why) override {
        done = state == ipc::CommandState::Done;
        reason = why;
      }
      bool done = false;
      std::string reason;
    } reporter;
    ipc::Command cmd{};
    cmd.type = ipc::CommandType::SimInject;
    cmd.text.assign(text);
    cmd.d[0] = value;
    EXPECT_TRUE(service->handle_command(cmd, reporter)) << text;
    EXPECT_TRUE(reporter.done) << text << ": " << reporter.reason;
    return reporter.done;
  }
  // Polls until `done` or 10 s pass (a loaded host is slow, never this slow).
  template <class F>
  bool eventually(F done) {
    for (int i = 0; i < 10'000; ++i) {
      if (done()) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return done();
  }

  std::string bus_name;
  ini::IniFile ini;
  hal::Hal hal;
  hal::ComponentRegistry registry;
  MessageQueue messages;
  std::unique_ptr<hal::CommandInterpreter> halcmd;
  hal::Thread* thread = nullptr;
  std::shared_ptr<can::VirtualBus> bus;
  ipc::ControllerService* service = nullptr;
  rt::CycleInfo info;
};

}  // namespace

TEST_F(SimStepper, ServoThreadOnItsOwnClockLeavesThePeriodToTheStepper) {
  ASSERT_NE(service, nullptr);
  cycle(true);
  // The stepper took the bus over from its boot-time real-time clock and
  // simulated the period; from now on bus time moves only when asked.
  ASSERT_TRUE(eventually([&] { return simulator().steps >= 1; }));
  const int64_t t0 = bus->now_ns();
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(bus->now_ns(), t0) << "no request, no bus time";
  for (int i = 0; i < 5; ++i) {
    cycle(true);
    ASSERT_TRUE(eventually([&] { return bus->now_ns() == t0 + (i + 1) * 1'000'000; })) << "cycle " << i;
  }
  const ipc::SimulatorStatus s = simulator();
  EXPECT_EQ(s.name.view(), "cia402-sim");
  EXPECT_GE(s.steps, 2u);
  EXPECT_GT(s.exec_max_ns, 0);
  EXPECT_EQ(s.late_steps, 0u) << "each period was simulated before the next was asked for";
  EXPECT_GT(thread->simulation_exec_max_ns(), 0) << "the update function is counted as the simulator's";
}

// A stepper that does not run (a loaded host without SCHED_FIFO): the
// period it has not started is simulated by the next cycle's update, with
// that cycle's own, so the drives' answers are never more than a cycle late.
TEST_F(SimStepper, PeriodTheStepperHasNotStartedIsCaughtUpByTheNextCycle) {
  cycle(true);
  ASSERT_TRUE(eventually([&] { return simulator().steps >= 1; }));
  const int64_t t0 = bus->now_ns();
  ASSERT_TRUE(inject("stepper hold", 1));
  cycle(true);  // asks for a period the held stepper will not simulate
  cycle(true);
  EXPECT_EQ(bus->now_ns(), t0 + 2'000'000) << "both periods simulated by the second cycle's update";
  ipc::SimulatorStatus s = simulator();
  EXPECT_EQ(s.late_steps, 1u);
  EXPECT_EQ(s.helped_steps, 1u);
  ASSERT_TRUE(inject("stepper hold", 0));
  cycle(true);
  EXPECT_TRUE(eventually([&] { return bus->now_ns() == t0 + 3'000'000; })) << "the stepper simulates again";
}

TEST_F(SimStepper, ThreadSteppedByHandSimulatesEachPeriodInline) {
  cycle(false);
  const int64_t t0 = bus->now_ns();
  for (int i = 1; i <= 5; ++i) {
    cycle(false);
    EXPECT_EQ(bus->now_ns(), t0 + i * 1'000'000) << "exactly one period per cycle, done when the cycle ends";
  }
  EXPECT_EQ(simulator().steps, 0u) << "the stepper stays out of a bus stepped by hand";
}
