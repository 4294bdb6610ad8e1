// The HAL component that gives every joint of motmod its screw compensation:
//   loadrt screwcomp [max_correction=1.0]      (after motmod)
// on_ready reads each joint's [JOINT_n]COMP_FILE (type COMP_FILE_TYPE) and
// attaches the tables to the motion controller; a joint without one gets
// BACKLASH as before, and a table loaded later (the JOINT_LOAD_COMP
// command) replaces either while the machine is stopped, without a
// restart. Pins per joint: screwcomp.N.correction (the correction the table
// asks for), screwcomp.N.entries, screwcomp.N.direction. The lookups run in
// the servo thread inside motion-controller; loading runs in the task cycle.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "comp/comp_table.hpp"
#include "core/hal/component.hpp"
#include "core/ipc/service.hpp"

namespace cnc {
class MessageQueue;
}
namespace cnc::motion {
class MotionComponent;
}

namespace cnc::comp {

class ScrewCompensation;

class ScrewCompComponent final : public hal::Component, public ipc::ControllerService {
 public:
  ScrewCompComponent(hal::ComponentContext& ctx, const hal::LoadArgs& args);
  ~ScrewCompComponent() override;

  void on_ready() override;

  // --- ControllerService: asked before the task controller (30) ---
  int service_order() const noexcept override { return 25; }
  bool handle_command(const ipc::Command& cmd, ipc::CommandReporter& reporter) override;
  void update(int64_t now_ns) override;
  void contribute_status(ipc::Status& status) override;

  int joints() const noexcept { return static_cast<int>(joints_.size()); }
  ScrewCompensation& compensation(int joint);

 private:
  struct Joint;
  struct Pending;
  // Why the machine is not stopped now ("" when it is).
  std::string why_not_stopped() const;
  void finish(bool taken);
  // Files longer than LinuxCNC's EMCMOT_COMP_SIZE are used whole here; the
  // message says so, as the same file would be cut short there.
  static constexpr std::size_t kLinuxCncMaxEntries = 256;
  void tell_if_longer_than_linuxcnc(int joint, const std::string& file, std::size_t entries);

  const ini::IniFile* ini_;
  MessageQueue* messages_;
  CompParseOptions parse_options_;
  motion::MotionComponent* motion_ = nullptr;
  std::vector<std::unique_ptr<Joint>> joints_;
  std::unique_ptr<Pending> pending_;
  bool program_idle_ = true;  // from the status block of the last task cycle
  int64_t now_ns_ = 0;
};

void register_components(hal::ComponentRegistry& registry);

}  // namespace cnc::comp
