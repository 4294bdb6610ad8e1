// A deterministic bench for the drive layer: simulated drives (cia402/sim)
// and the CANopen master on a virtual bus with a manual clock, and the
// master-side drive group on top, stepped by hand. One servo cycle is:
// bus read, drives read, the test's "motion" (commands), drives write, bus
// write; between cycles the bus, the simulators and the master's acyclic
// side advance in small steps. Everything here is the production code;
// only the clock and the threads are the test's.
#pragma once

#include <functional>
#include <future>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "fieldbus/canopen/cia402_binding.hpp"
#include "cia402/drive_group.hpp"
#include "sim/cia402/sim_config.hpp"
#include "sim/cia402/sim_host.hpp"
#include "core/ini/ini_file.hpp"
#include "core/util/messages.hpp"
#include "sim/can/virtual_bus.hpp"
#include "fieldbus/canopen/config.hpp"
#include "fieldbus/canopen/master.hpp"
#include "tests/support/testing.hpp"

namespace cnc::cia402::test {

// One axis, everything mapped (7 PDOs): the master's optional paths are
// exercised by tests that remove entries.
inline std::string one_axis_ini() {
  return R"(
[EMCMOT]
SERVO_PERIOD = 1000000

[JOINT_0]
HOME_OFFSET = 10

[CANOPEN]
INTERFACE = virtual:rig
NODE = 1
MASTER_HEARTBEAT_MS = 20
PDO_MISS_LIMIT = 3
MAX_BUS_LOAD = 100
# Everything synchronous on one axis: 920 bit times per cycle. The rig has
# no EMCY or SDO allowance in its plan (a cycle with an EMCY or SDO frame
# may see a TPDO late, which PDO_MISS_LIMIT = 3 tolerates).
MAX_CYCLE_LOAD = 100
EMCY_FRAMES_PER_CYCLE = 0
SDO_FRAMES_PER_CYCLE = 0

[CANOPEN_NODE_1]
NAME = x-axis
HEARTBEAT_MS = 20
HEARTBEAT_TIMEOUT_MS = 100
MASTER_HEARTBEAT_TIMEOUT_MS = 60
RPDO1 = 0x6040:0:u16 0x607A:0:s32 0x6060:0:s8
RPDO2 = 0x60FF:0:s32 0x6071:0:s16 0x60B8:0:u16
TPDO1 = 0x6041:0:u16 0x6064:0:s32 0x6061:0:s8
TPDO2 = 0x606C:0:s32 0x60F4:0:s32
TPDO3 = 0x6077:0:s16 0x603F:0:u16 0x60FD:0:u32
TPDO4 = 0x60B9:0:u16 0x60BA:0:s32
TPDO5 = 0x60BC:0:s32
TPDO5_COB_ID = 0x1E1

[CIA402]
BUS = canopen.0
DRIVE = 0
WATCHDOG_CYCLES = 3

[CIA402_DRIVE_0]
ADDRESS = 1
NAME = x-axis
JOINT = 0
ENCODER_COUNTS = 10000
SCREW_LEAD = 5
FERROR_WINDOW = 1
FERROR_TIMEOUT_MS = 20
QUICK_STOP_DECEL = 2000
HOME_METHOD = 0
HOME_SEARCH_VEL = 20
HOME_LATCH_VEL = 2
HOME_ACCEL = 500
ENABLE_TIMEOUT_MS = 200
FAULT_RESET_HOLDOFF_MS = 200

[CIA402_SIM]
INTERFACE = virtual:rig
NODE = 1

[CIA402_SIM_NODE_1]
NAME = x-axis
ENCODER_COUNTS = 10000
SCREW_LEAD = 5
LOAD_MASS = 200
NEG_LIMIT_SWITCH = -100
POS_LIMIT_SWITCH = 100
HOME_SWITCH = 40
INDEX_OFFSET = 1.3
SYNC_TIMEOUT_MS = 50
)";
}

class Rig {
 public:
  static constexpr int64_t kStepNs = 20'000;

  explicit Rig(const std::string& ini_text, const std::function<void(ini::IniFile&)>& edit = {})
      : ini_(ini::IniFile::parse(ini_text, "rig.ini")) {
    if (edit) edit(ini_);
    can::VirtualBusOptions o;
    o.manual_clock = true;
    bus_ = can::VirtualBus::create(o);
    sim_port_ = bus_->open_port("sim");
    host_ = std::make_unique<sim::SimHost>(*sim_port_);
    // Each drive a controller of its own on the bus, as cia402_sim does.
    for (const auto& n : sim::load_sim_config(ini_, "CIA402_SIM").nodes) {
      host_->add(n, bus_->open_port("sim-" + std::to_string(n.node_id)));
    }
    host_->power_on(now());
    // The rig's cycles stand for the HAL thread that runs the bus: its
    // period is the test INI's [EMCMOT]SERVO_PERIOD.
    canopen::BusConfig bc =
        canopen::load_bus_config(ini_, "CANOPEN", "canopen.0", ini_.get_int("EMCMOT", "SERVO_PERIOD", 1'000'000));
    cycle_ns_ = bc.cycle_ns;
    master_ = std::make_unique<canopen::Master>(std::move(bc), bus_->open_port("cyclic"), bus_->open_port("acyclic"),
                                                &messages);
    master_->begin_boot();
    run_for(10'000'000);
    while (master_->boot_state() == canopen::BootState::Running && now() < 6'000'000'000) step();
    if (master_->boot_state() != canopen::BootState::Succeeded) {
      throw std::runtime_error("rig: boot failed: " + master_->boot_error());
    }
    link_ = std::make_unique<SteppedLink>(*this, canopen::make_cia402_link(*master_));
    group_ = std::make_unique<DriveGroup>(load_group_config(ini_, "CIA402", "cia402.0"), *link_, &messages);
  }

  // Start-up writes (a test may skip them to see what the drive does by default).
  void configure() { group_->configure(); }

  int64_t now() const { return bus_->now_ns(); }
  void step() {
    bus_->advance(kStepNs);
    if (sim_stalled && sim_stalled(now())) {
      if (stalled_since_ < 0) stalled_since_ = now();
    } else {
      // A stalled pass read the clock before it stalled: its `now` is then.
      host_->step(stalled_since_ >= 0 ? stalled_since_ : now());
      stalled_since_ = -1;
    }
    if (after_step) after_step(*this);
    if (!master_dead_ && !acyclic_stalled_) master_->poll(now());
  }
  void run_for(int64_t ns) {
    const int64_t end = now() + ns;
    while (now() < end) step();
  }

  // One servo cycle; `motion` sets the commands between read and write.
  void cycle(const std::function<void(Rig&)>& motion = {}) {
    const int64_t t = now();
    if (!master_dead_) {
      // The servo thread's functions, optionally under the allocation counter.
      if (count_allocations) cnc::testing::AllocationCounter::arm_this_thread();
      master_->cyclic_read(t);
      group_->read(t);
      if (count_allocations) cnc::testing::AllocationCounter::disarm_this_thread();
      if (motion) motion(*this);
      if (before_write) before_write(*this);
      if (count_allocations) cnc::testing::AllocationCounter::arm_this_thread();
      group_->write(t);
      if (!bus_muted_) master_->cyclic_write(t);
      if (count_allocations) cnc::testing::AllocationCounter::disarm_this_thread();
    }
    ++cycles_;
    const int64_t end = t + cycle_ns_;
    while (now() < end) step();
  }
  void cycles(int n, const std::function<void(Rig&)>& motion = {}) {
    for (int i = 0; i < n; ++i) cycle(motion);
  }
  // Cycles until `pred` holds (checked after each cycle); false on timeout.
  bool cycle_until(const std::function<bool()>& pred, int max_cycles, const std::function<void(Rig&)>& motion = {}) {
    for (int i = 0; i < max_cycles; ++i) {
      cycle(motion);
      if (pred()) return true;
    }
    return false;
  }

  DriveCommand& cmd(std::size_t i = 0) { return group_->command(i); }
  const DriveFeedback& fb(std::size_t i = 0) const { return group_->feedback(i); }
  DriveGroup& group() { return *group_; }
  canopen::Master& master() { return *master_; }
  sim::SimHost& host() { return *host_; }
  sim::DriveModel& sim(std::size_t i = 0) { return host_->at(i).model(); }
  can::VirtualBus& bus() { return *bus_; }
  const ini::IniFile& ini() const { return ini_; }
  uint64_t cycle_count() const { return cycles_; }
  // Stops the master's cyclic output (the bus's enable pin) when true.
  void mute_bus(bool on) { bus_muted_ = on; }
  // The whole master dies: no cycle, no heartbeat, no SDO.
  void kill_master() { master_dead_ = true; }
  // The master's acyclic thread gets no CPU (normal priority under load)
  // while the servo thread runs on.
  void stall_acyclic(bool on) { acyclic_stalled_ = on; }

  // Every message posted so far, as text lines "source: text".
  std::vector<std::string> drain_messages() {
    Message m;
    while (messages.pop(m)) log.push_back(std::string(to_string(m.kind)) + " " + m.source.c_str() + ": " + m.text.c_str());
    return log;
  }
  bool has_message(const std::string& part) {
    drain_messages();
    for (const auto& l : log) {
      if (l.find(part) != std::string::npos) return true;
    }
    return false;
  }

  // Enables the drive and waits until it follows; false on timeout.
  bool enable(std::size_t i = 0, int max_cycles = 300) {
    cmd(i).enable = true;
    cmd(i).pos_cmd = fb(i).pos_fb;
    return cycle_until([&] { return fb(i).enabled; }, max_cycles, [&](Rig& r) {
      if (!r.fb(i).enabled) r.cmd(i).pos_cmd = r.fb(i).pos_fb;
    });
  }

  MessageQueue messages;
  std::vector<std::string> log;
  std::function<void(Rig&)> before_write;
  bool count_allocations = false;  // arm the allocation counter around the servo-thread calls
  // While it returns true the simulators' process is stalled in the middle of
  // a pass: it read the clock when the pass began, then lost the CPU; frames
  // wait in its socket and are read together, with their reception times,
  // when it runs again, by the pass that still has the old time.
  std::function<bool(int64_t now_ns)> sim_stalled;
  // Called after every step of the bus and the simulators (observation).
  std::function<void(Rig&)> after_step;

 private:
  // The production link, except that the blocking start-up transfers step
  // the rig until they finish (there is no acyclic thread here).
  class SteppedLink final : public DriveLink {
   public:
    SteppedLink(Rig& rig, std::unique_ptr<DriveLink> inner) : rig_(rig), inner_(std::move(inner)) {}
    const std::string& name() const noexcept override { return inner_->name(); }
    const char* loss_causes() const noexcept override { return inner_->loss_causes(); }
    bool has_device(int a) const noexcept override { return inner_->has_device(a); }
    Slot output(int a, Object o) const noexcept override { return inner_->output(a, o); }
    Slot input(int a, Object o) const noexcept override { return inner_->input(a, o); }
    uint64_t input_sequence(const Slot& s) const noexcept override { return inner_->input_sequence(s); }
    int64_t cycle_ns() const noexcept override { return inner_->cycle_ns(); }
    LinkHealth health(int a) const noexcept override { return inner_->health(a); }
    int request_read(int a, Object o) noexcept override { return inner_->request_read(a, o); }
    int request_write(int a, Object o, uint32_t v, unsigned size) noexcept override {
      return inner_->request_write(a, o, v, size);
    }
    bool poll(int h, AcyclicResult& out) noexcept override { return inner_->poll(h, out); }
    ConfigResult read_wait(int a, Object o, unsigned size) override {
      return wait([&](canopen::SdoClient::Done done) {
        rig_.master().sdo_upload(static_cast<uint8_t>(a), {o.index, o.sub}, std::move(done));
      }, size);
    }
    ConfigResult write_wait(int a, Object o, uint64_t value, unsigned size) override {
      std::vector<uint8_t> data(size);
      for (unsigned i = 0; i < size; ++i) data[i] = static_cast<uint8_t>(value >> (8 * i));
      return wait([&](canopen::SdoClient::Done done) {
        rig_.master().sdo_download(static_cast<uint8_t>(a), {o.index, o.sub}, std::move(data), std::move(done));
      }, size);
    }

   private:
    ConfigResult wait(const std::function<void(canopen::SdoClient::Done)>& start, unsigned size) {
      auto result = std::make_shared<std::optional<canopen::SdoResult>>();
      start([result](const canopen::SdoResult& r) { *result = r; });
      const int64_t end = rig_.now() + 2'000'000'000;
      while (!*result && rig_.now() < end) rig_.step();
      ConfigResult out;
      if (!*result) {
        out.text = "rig: SDO did not finish";
        return out;
      }
      const canopen::SdoResult& r = **result;
      out.ok = r.ok();
      out.abort_code = r.abort_code;
      if (!r.ok()) out.text = r.message();
      for (std::size_t i = 0; i < r.data.size() && i < 8 && i < size; ++i) out.value |= uint64_t{r.data[i]} << (8 * i);
      return out;
    }
    Rig& rig_;
    std::unique_ptr<DriveLink> inner_;
  };

  ini::IniFile ini_;
  std::shared_ptr<can::VirtualBus> bus_;
  std::unique_ptr<can::VirtualPort> sim_port_;
  std::unique_ptr<sim::SimHost> host_;
  std::unique_ptr<canopen::Master> master_;
  std::unique_ptr<DriveLink> link_;
  std::unique_ptr<DriveGroup> group_;
  int64_t cycle_ns_ = 1'000'000;
  uint64_t cycles_ = 0;
  bool bus_muted_ = false;
  bool master_dead_ = false;
  bool acyclic_stalled_ = false;
  int64_t stalled_since_ = -1;
};

}  // namespace cnc::cia402::test
