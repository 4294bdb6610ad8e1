// An in-process simulated mill for task and I/O tests: the HAL of
// tests/core/task/mill driven cycle by cycle (servo thread functions, then one task
// cycle), with the test planner behind motion (or any other planner the
// test passes in). Deterministic and fast.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <array>
#include <fstream>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "core/daemon/controller.hpp"
#include "core/hal/commands.hpp"
#include "core/io/io_controller.hpp"
#include "core/motion/motion_component.hpp"
#include "core/task/task_controller.hpp"
#include "core/util/messages.hpp"
#include "kinematics/kinematics.hpp"
#include "sim/machine/components.hpp"
#include "tests/core/motion/simple_planner.hpp"
#include "tests/support/testing.hpp"

namespace cnc::testing {

class Reporter : public ipc::CommandReporter {
 public:
  void report(const ipc::Command& cmd, ipc::CommandState state, std::string_view reason) override {
    last[cmd.serial] = {state, std::string(reason)};
  }
  std::map<uint32_t, std::pair<ipc::CommandState, std::string>> last;
};

class TaskMachine {
 public:
  // The machine is tests/core/task/mill: configs/sim as it was before its
  // axes became CiA 402 drives (ideal sim_joint axes), so that these tests
  // are about the task and I/O controllers, not drive timing.
  // `ini_extra` is appended to its sim.ini; `hal_extra` to sim.hal.
  // `planner_factory` makes motion's trajectory planner (default: the
  // exact-stop SimplePlanner of tests/core/motion).
  using Override = std::array<std::string, 3>;  // section, key, value
  explicit TaskMachine(const std::vector<Override>& overrides = {}, const std::string& hal_extra = "",
                       const std::string& tool_table = "", const std::string& ini_extra = "",
                       motion::PlannerFactory planner_factory = simple_planner_factory()) {
    const auto src = source_dir() / "tests/core/task/mill";
    std::string ini = read(src / "sim.ini") + "\n" + ini_extra;
    dir.write("sim.ini", ini);
    dir.write("sim.hal", read(src / "sim.hal") + "\n" + hal_extra);
    dir.write("tool.tbl", tool_table.empty() ? read(src / "tool.tbl") : tool_table);
    std::filesystem::create_directories(dir / "nc_files");
    ini_ = ini::IniFile::load(dir / "sim.ini");
    for (const auto& [section, key, value] : overrides) ini_.set(section, key, value);
    hal::register_core_components(registry_);
    kin::register_kinematics_components(registry_);
    motion::register_components(registry_, std::move(planner_factory));
    sim::register_sim_joint(registry_);
    sim::register_sim_toolchanger(registry_);
    hal_.add_component(std::make_unique<io::IoController>(hal_, io::IoConfig::from_ini(ini_), &messages));
    hal::CommandInterpreter interp(hal_, registry_, &ini_, &messages);
    interp.run_file(dir / "sim.hal");
    for (hal::Component* c : hal_.components()) c->on_ready();
    motion_ = hal_.find<motion::MotionComponent>("motmod");
    io_ = hal_.find<io::IoController>("iocontrol");
    task_ = std::make_unique<task::TaskController>(ini_, hal_, *motion_, *io_, messages);
    // As the daemon wires them: the E-stop words (here not in a segment)
    // and the E-stop chain.
    motion_->set_estop_inputs(&estop, io_->estop_chain_pin());
    thread_ = hal_.find_thread("servo-thread");
    info_.period_ns = info_.actual_period_ns = 1'000'000;
  }

  static motion::PlannerFactory simple_planner_factory() {
    return [](const tp::PlannerConfig& c) -> std::unique_ptr<tp::TrajectoryPlanner> {
      return std::make_unique<SimplePlanner>(c);
    };
  }

  void step(int n = 1) {
    for (int i = 0; i < n; ++i) {
      thread_->run_cycle(info_);
      ++info_.cycle;
      task_cycle();
    }
  }
  // One task cycle without a servo cycle; the services in the daemon's order.
  void task_cycle() {
    const int64_t now = monotonic_ns();
    motion_->update(now);
    io_->update(now);
    task_->update(now);
  }
  // Servo cycles only: the task cycle stalls meanwhile.
  void servo_only(int n = 1) {
    for (int i = 0; i < n; ++i) {
      thread_->run_cycle(info_);
      ++info_.cycle;
    }
  }
  template <class Pred>
  bool run_until(Pred pred, int max_cycles = 200000) {
    for (int i = 0; i < max_cycles; ++i) {
      if (pred()) return true;
      step();
    }
    return pred();
  }

  // Sends a command and steps until it is answered (Done or Rejected).
  std::pair<ipc::CommandState, std::string> send(ipc::Command c, int max_cycles = 200000) {
    c.serial = ++serial_;
    if (!task_->handle_command(c, reporter)) return {ipc::CommandState::None, "not handled"};
    for (int i = 0; i < max_cycles; ++i) {
      const auto it = reporter.last.find(c.serial);
      if (it != reporter.last.end() &&
          (it->second.first == ipc::CommandState::Done || it->second.first == ipc::CommandState::Rejected)) {
        return it->second;
      }
      step();
    }
    return reporter.last[c.serial];
  }
  std::pair<ipc::CommandState, std::string> send(ipc::CommandType t, int i0 = 0, double d0 = 0) {
    ipc::Command c;
    c.type = t;
    c.i[0] = i0;
    c.d[0] = d0;
    return send(c);
  }
  std::pair<ipc::CommandState, std::string> mdi(const std::string& text) {
    ipc::Command c;
    c.type = ipc::CommandType::TaskPlanExecute;
    c.i[0] = -1;
    c.text.assign(text);
    return send(c);
  }
  std::pair<ipc::CommandState, std::string> open(const std::string& name, const std::string& program) {
    const auto p = dir.write("nc_files/" + name, program);
    ipc::Command c;
    c.type = ipc::CommandType::TaskPlanOpen;
    c.text.assign(p.string());
    return send(c);
  }
  void ok(std::pair<ipc::CommandState, std::string> r, const char* what) {
    ASSERT_EQ(r.first, ipc::CommandState::Done) << what << ": " << r.second << "\n" << errors();
  }
  // E-stop reset, machine on, home all.
  void power_up_and_home() {
    ok(send(ipc::CommandType::TaskSetState, 2), "estop reset");
    ok(send(ipc::CommandType::TaskSetState, 4), "machine on");
    ok(send(ipc::CommandType::JointHome, -1), "home all");
  }
  ipc::Status status() {
    ipc::Status s{};
    for (hal::Component* c : hal_.components()) {
      if (auto* svc = dynamic_cast<ipc::ControllerService*>(c)) svc->contribute_status(s);
    }
    task_->contribute_status(s);
    return s;
  }
  bool program_running() { return task_->interp_state() != ipc::InterpState::Idle; }
  std::string errors() {
    std::string out;
    Message m;
    while (messages.pop(m)) {
      if (m.kind == MessageKind::Error) out += std::string(m.source.view()) + ": " + std::string(m.text.view()) + "\n";
      log += std::string(to_string(m.kind)) + " " + std::string(m.text.view()) + "\n";
    }
    return out;
  }
  static std::string read_text(const std::filesystem::path& p) { return read(p); }
  hal::Hal& hal() { return hal_; }
  // What the servo thread's periodic task tells each cycle (tests set the
  // overrun figures, as after a stall).
  rt::CycleInfo& cycle_info() { return info_; }
  task::TaskController& task() { return *task_; }
  io::IoController& io() { return *io_; }
  motion::MotionComponent& motion() { return *motion_; }

  TempDir dir;
  ipc::EstopWords estop;
  MessageQueue messages;
  Reporter reporter;
  std::string log;

 private:
  static std::string read(const std::filesystem::path& p) {
    std::ifstream in(p);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }
  ini::IniFile ini_;
  hal::Hal hal_;
  hal::ComponentRegistry registry_;
  motion::MotionComponent* motion_ = nullptr;
  io::IoController* io_ = nullptr;
  std::unique_ptr<task::TaskController> task_;
  hal::Thread* thread_ = nullptr;
  rt::CycleInfo info_;
  uint32_t serial_ = 0;
};

}  // namespace cnc::testing
