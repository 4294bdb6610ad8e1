// A simulated machine for the compensation closed loop, in-process and
// stepped cycle by cycle in simulated time: a configuration folder (INI and
// HAL files) is copied to a temporary folder and built as the controller
// builds it (HAL files, every component's on_ready, the I/O and task
// controllers); each step runs the servo thread once, then one task cycle
// with the services in the daemon's order. Commands reach the services as
// the daemon dispatches them, so JOINT_LOAD_COMP goes to screwcomp.
// Used by the closed-loop test and the benchmark; no GoogleTest inside.
#pragma once

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "comp/measurement_logger.hpp"
#include "comp/screwcomp_component.hpp"
#include "core/hal/commands.hpp"
#include "core/ini/ini_file.hpp"
#include "core/io/io_controller.hpp"
#include "core/motion/motion_component.hpp"
#include "core/task/task_controller.hpp"
#include "core/tp/lookahead_planner.hpp"
#include "core/util/atomic_file.hpp"
#include "core/util/messages.hpp"
#include "kinematics/kinematics.hpp"
#include "sim/register.hpp"

namespace cnc::testing {

class SimMill : private ipc::CommandReporter {
 public:
  using Registrar = std::function<void(hal::ComponentRegistry&)>;
  using Reply = std::pair<ipc::CommandState, std::string>;

  // `extra_hal`: halcmd lines run after the INI's HAL files (the
  // compensation's components added to a configuration that lacks them).
  SimMill(const std::filesystem::path& config, const std::filesystem::path& work, const std::string& ini_name,
          const Registrar& extra, const std::string& extra_hal = "", motion::PlannerFactory planner = {})
      : dir_(work) {
    std::filesystem::create_directories(dir_);
    std::filesystem::copy(config, dir_,
                          std::filesystem::copy_options::recursive | std::filesystem::copy_options::overwrite_existing);
    ini_ = ini::IniFile::load(dir_ / ini_name);
    hal::register_core_components(registry_);
    kin::register_kinematics_components(registry_);
    if (!planner) planner = [](const tp::PlannerConfig& c) { return tp::make_planner(c); };
    motion::register_components(registry_, planner);
    sim::register_components(registry_);  // sim_toolchanger, cia402_sim and their buses
    comp::register_components(registry_);
    if (extra) extra(registry_);
    hal_.add_component(std::make_unique<io::IoController>(hal_, io::IoConfig::from_ini(ini_), &messages_));
    hal::CommandInterpreter interp(hal_, registry_, &ini_, &messages_);
    for (const std::string& f : ini_.find_all("HAL", "HALFILE")) interp.run_file(ini_.resolve_path(f));
    if (!extra_hal.empty()) {
      write_file_atomically(dir_ / "extra.hal", extra_hal);
      interp.run_file(dir_ / "extra.hal");
    }
    for (hal::Component* c : hal_.components()) c->on_ready();
    motion_ = hal_.find<motion::MotionComponent>("motmod");
    io_ = hal_.find<io::IoController>("iocontrol");
    task_ = std::make_unique<task::TaskController>(ini_, hal_, *motion_, *io_, messages_);
    for (hal::Component* c : hal_.components()) {
      if (auto* s = dynamic_cast<ipc::ControllerService*>(c)) services_.push_back(s);
    }
    services_.push_back(task_.get());
    std::stable_sort(services_.begin(), services_.end(), [](const ipc::ControllerService* a, const ipc::ControllerService* b) {
      return a->service_order() < b->service_order();
    });
    thread_ = hal_.find_thread("servo-thread");
    info_.period_ns = info_.actual_period_ns = 1'000'000;
    status_ = std::make_unique<ipc::Status>();
  }

  // One servo period, then one task cycle.
  void step(int n = 1) {
    for (int i = 0; i < n; ++i) {
      info_.now_ns = now_ns_;  // simulated time: drives and bus masters time out on it
      thread_->run_cycle(info_);
      if (on_cycle) on_cycle();
      ++info_.cycle;
      now_ns_ += info_.period_ns;
      for (ipc::ControllerService* s : services_) s->update(now_ns_);
      if (pace) pace();
      if (info_.cycle % 10 == 0) {
        for (ipc::ControllerService* s : services_) s->contribute_status(*status_);
      }
      drain();
    }
  }

  Reply send(ipc::Command c, int max_cycles = 600000) {
    c.serial = ++serial_;
    // A client sends its next command once it has seen the state it waits
    // for in the published status: publish it (this harness does so only
    // every 10th cycle, to save time), twice, because a service may read
    // another's part (screwcomp reads the task's interpreter state, and
    // comes first): it could still take a program that had just ended for a
    // running one and refuse JOINT_LOAD_COMP (1 closed-loop run in 6).
    for (int pass = 0; pass < 2; ++pass) {
      for (ipc::ControllerService* s : services_) s->contribute_status(*status_);
    }
    bool taken = false;
    for (ipc::ControllerService* s : services_) {
      if ((taken = s->handle_command(c, *this))) break;
    }
    if (!taken) return {ipc::CommandState::Rejected, "no service handles it"};
    for (int i = 0; i < max_cycles; ++i) {
      const auto it = replies_.find(c.serial);
      if (it != replies_.end() &&
          (it->second.first == ipc::CommandState::Done || it->second.first == ipc::CommandState::Rejected)) {
        return it->second;
      }
      step();
    }
    return {ipc::CommandState::None, "no answer in time"};
  }
  Reply send(ipc::CommandType t, int i0 = 0, double d0 = 0) {
    ipc::Command c;
    c.type = t;
    c.i[0] = i0;
    c.d[0] = d0;
    return send(c);
  }

  // E-stop reset, machine on, home all, auto mode. Empty on success.
  // "Machine on" is done once every drive follows (joint.N.amp-ready-in),
  // so homing goes right after it.
  std::string power_up() {
    const auto check = [&](const char* what, const Reply& reply) {
      return reply.first == ipc::CommandState::Done ? std::string() : std::string(what) + ": " + reply.second + errors();
    };
    if (std::string e = check("estop reset", send(ipc::CommandType::TaskSetState, 2)); !e.empty()) return e;
    if (std::string e = check("machine on", send(ipc::CommandType::TaskSetState, 4)); !e.empty()) return e;
    if (std::string e = check("home all", send(ipc::CommandType::JointHome, -1)); !e.empty()) return e;
    return check("auto", send(ipc::CommandType::TaskSetMode, static_cast<int>(ipc::TaskMode::Auto)));
  }

  // Writes, opens and runs a program until the interpreter is idle again.
  std::string run_program(const std::string& name, const std::string& text, double max_seconds) {
    write_file_atomically(dir_ / name, text);
    ipc::Command open;
    open.type = ipc::CommandType::TaskPlanOpen;
    open.text.assign((dir_ / name).string());
    if (const Reply r = send(open); r.first != ipc::CommandState::Done) return "open: " + r.second + errors();
    ipc::Command run;
    run.type = ipc::CommandType::TaskPlanRun;
    run.serial = ++serial_;
    for (ipc::ControllerService* s : services_) {
      if (s->handle_command(run, *this)) break;
    }
    const int64_t limit = now_ns_ + static_cast<int64_t>(max_seconds * 1e9);
    step(20);
    while (task_->interp_state() != ipc::InterpState::Idle) {
      if (now_ns_ > limit) return "program did not end within " + std::to_string(max_seconds) + " s" + errors();
      step(100);
    }
    const auto it = replies_.find(run.serial);
    if (it != replies_.end() && it->second.first == ipc::CommandState::Rejected) return "run: " + it->second.second;
    const std::string e = errors();
    return e.empty() ? std::string() : "errors while running: " + e;
  }

  // JOINT_LOAD_COMP as a client sends it.
  Reply load_comp(int joint, const std::filesystem::path& file, int type) {
    ipc::Command c;
    c.type = ipc::CommandType::JointLoadComp;
    c.i[0] = joint;
    c.i[1] = type;
    c.text.assign(file.string());
    return send(c);
  }

  // Called after every servo cycle (benchmarks sample pins here).
  std::function<void()> on_cycle;
  // Called after every step: may wait for threads the simulated time must
  // not outrun (tests/fieldbus/canopen/pace.hpp).
  std::function<void()> pace;
  // Every message on stderr with its simulated time (SIMMILL_VERBOSE=1).
  bool verbose = std::getenv("SIMMILL_VERBOSE") != nullptr;

  comp::MeasurementLogger& logger() { return *hal_.find<comp::MeasurementLogger>("complog"); }
  hal::Hal& hal() { return hal_; }
  motion::MotionComponent& motion() { return *motion_; }
  const ipc::Status& status() const { return *status_; }
  double seconds() const { return static_cast<double>(now_ns_ - kStartNs) * 1e-9; }
  const std::filesystem::path& dir() const { return dir_; }
  // Error messages since the last call.
  std::string errors() {
    drain();
    std::string e;
    e.swap(errors_);
    return e;
  }

 private:
  void report(const ipc::Command& cmd, ipc::CommandState state, std::string_view reason) override {
    replies_[cmd.serial] = {state, std::string(reason)};
  }
  void drain() {
    Message m;
    while (messages_.pop(m)) {
      if (verbose) {
        std::fprintf(stderr, "[%9.3f s] %s %s: %s\n", seconds(), to_string(m.kind), m.source.c_str(), m.text.c_str());
      }
      if (m.kind == MessageKind::Error) errors_ += "\n  " + std::string(m.source.view()) + ": " + std::string(m.text.view());
    }
  }

  std::filesystem::path dir_;
  MessageQueue messages_;
  ini::IniFile ini_;
  hal::Hal hal_;
  hal::ComponentRegistry registry_;
  motion::MotionComponent* motion_ = nullptr;
  io::IoController* io_ = nullptr;
  std::unique_ptr<task::TaskController> task_;
  std::vector<ipc::ControllerService*> services_;
  std::unique_ptr<ipc::Status> status_;
  hal::Thread* thread_ = nullptr;
  rt::CycleInfo info_;
  static constexpr int64_t kStartNs = 1'000'000'000'000;  // a clock that has run for a while, as CLOCK_MONOTONIC has
  int64_t now_ns_ = kStartNs;
  uint32_t serial_ = 0;
  std::map<uint32_t, Reply> replies_;
  std::string errors_;
};

}  // namespace cnc::testing
