#include "comp/screwcomp_component.hpp"

#include <cmath>

#include "comp/screw_compensation.hpp"
#include "core/ini/ini_file.hpp"
#include "core/motion/motion_component.hpp"
#include "core/util/error.hpp"
#include "core/util/messages.hpp"

namespace cnc::comp {

struct ScrewCompComponent::Joint final : motion::JointCompensation {
  ScrewCompensation table;
  hal::FloatPin correction_pin;
  hal::S32Pin entries_pin, direction_pin;

  bool correction(double pos_cmd, double vel_cmd, double& value) noexcept override {
    const bool has = table.correction(pos_cmd, vel_cmd, value);
    correction_pin.set(has ? value : 0.0);
    entries_pin.set(static_cast<int32_t>(table.entries()));
    direction_pin.set(table.direction());
    return has;
  }
};

struct ScrewCompComponent::Pending {
  ipc::Command cmd;
  ipc::CommandReporter* reporter = nullptr;
  int joint = 0;
  std::string file;
  std::size_t entries = 0;
  uint64_t switches_before = 0;
  int64_t deadline_ns = 0;
  bool started = false;  // the deadline counts from the first update after the offer
};

namespace {
constexpr int64_t kTakeOverTimeoutNs = 2'000'000'000;
}

ScrewCompComponent::ScrewCompComponent(hal::ComponentContext& ctx, const hal::LoadArgs& args)
    : hal::Component(ctx.hal, "screwcomp"), ini_(ctx.ini), messages_(ctx.messages) {
  args.allow_only({"max_correction"});
  parse_options_.max_abs_trim = args.get_double("max_correction", 1.0);
  if (!(parse_options_.max_abs_trim > 0)) throw hal::HalError("screwcomp: max_correction must be positive");
  motion_ = ctx.hal.find<motion::MotionComponent>("motmod");
  if (!motion_) throw hal::HalError("screwcomp: load motmod first (loadrt screwcomp comes after loadrt motmod)");
  const int n = motion_->config().num_joints;
  for (int j = 0; j < n; ++j) {
    auto jt = std::make_unique<Joint>();
    const std::string p = "screwcomp." + std::to_string(j) + ".";
    jt->correction_pin = make_pin<double>(p + "correction", hal::PinDir::Out);
    jt->entries_pin = make_pin<int32_t>(p + "entries", hal::PinDir::Out);
    jt->direction_pin = make_pin<int32_t>(p + "direction", hal::PinDir::Out);
    joints_.push_back(std::move(jt));
  }
}

ScrewCompComponent::~ScrewCompComponent() = default;

ScrewCompensation& ScrewCompComponent::compensation(int joint) { return joints_.at(static_cast<std::size_t>(joint))->table; }

void ScrewCompComponent::on_ready() {
  if (!motion_->ready()) {
    throw hal::HalError("screwcomp: motmod is not ready (load screwcomp after motmod so that it starts after it)");
  }
  const motion::MotionConfig& cfg = motion_->config();
  for (int j = 0; j < static_cast<int>(joints_.size()); ++j) {
    const motion::JointConfig& jc = cfg.joints[static_cast<std::size_t>(j)];
    Joint& jt = *joints_[static_cast<std::size_t>(j)];
    if (!jc.comp_file.empty()) {
      CompTable t = load_comp_file(jc.comp_file, static_cast<CompFileType>(jc.comp_file_type), parse_options_);
      if (jc.backlash > 0 && messages_) {
        messages_->postf(MessageKind::Text, "screwcomp",
                         "joint %d: BACKLASH %g is not applied: COMP_FILE %s gives the correction (as in LinuxCNC)", j,
                         jc.backlash, jc.comp_file.c_str());
      }
      tell_if_longer_than_linuxcnc(j, jc.comp_file, t.size());
      jt.table.install(std::move(t));
    }
    jt.entries_pin.set(static_cast<int32_t>(jt.table.entries()));
    motion_->set_compensation(j, &jt);
  }
}

void ScrewCompComponent::tell_if_longer_than_linuxcnc(int joint, const std::string& file, std::size_t entries) {
  if (entries <= kLinuxCncMaxEntries || !messages_) return;
  messages_->postf(MessageKind::Text, "screwcomp",
                   "joint %d: %s has %zu entries, all in use here; LinuxCNC 2.9 would use only the first %zu", joint,
                   file.c_str(), entries, kLinuxCncMaxEntries);
}

std::string ScrewCompComponent::why_not_stopped() const {
  const motion::MotionStatus s = motion_->status();
  if (!program_idle_) return "a program or MDI command is running";
  if (s.any_homing) return "a joint is homing";
  if (s.jogging) return "a joint is jogging";
  if (!s.traj.inpos || !s.tp_done) return "the machine is moving";
  for (int j = 0; j < static_cast<int>(joints_.size()); ++j) {
    if (s.joints[j].velocity != 0) return "joint " + std::to_string(j) + " is moving";
  }
  return {};
}

bool ScrewCompComponent::handle_command(const ipc::Command& cmd, ipc::CommandReporter& reporter) {
  if (cmd.type != ipc::CommandType::JointLoadComp) return false;
  const int j = cmd.i[0];
  const int type = cmd.i[1];
  std::string file(cmd.text.view());
  const auto reject = [&](const std::string& why) { reporter.report(cmd, ipc::CommandState::Rejected, why); };
  if (j < 0 || j >= static_cast<int>(joints_.size())) {
    reject("no joint " + std::to_string(j) + " (there are " + std::to_string(joints_.size()) + ")");
    return true;
  }
  if (type != 0 && type != 1) {
    reject("COMP_FILE_TYPE " + std::to_string(type) + " is not 0 (positions) or 1 (trims)");
    return true;
  }
  if (file.empty()) {
    reject("no compensation file named");
    return true;
  }
  if (pending_) {
    reject("joint " + std::to_string(pending_->joint) + " is still taking its table; try again");
    return true;
  }
  if (const std::string why = why_not_stopped(); !why.empty()) {
    reject("tables are replaced only while the machine is stopped: " + why);
    return true;
  }
  if (ini_ && std::filesystem::path(file).is_relative()) file = ini_->resolve_path(file).string();
  CompTable table;
  try {
    table = load_comp_file(file, static_cast<CompFileType>(type), parse_options_);
  } catch (const std::exception& e) {
    reject(e.what());
    return true;
  }
  Joint& jt = *joints_[static_cast<std::size_t>(j)];
  pending_ = std::make_unique<Pending>();
  pending_->cmd = cmd;
  pending_->reporter = &reporter;
  pending_->joint = j;
  pending_->file = file;
  pending_->entries = table.size();
  pending_->switches_before = jt.table.switches();
  jt.table.offer(std::move(table));
  reporter.report(cmd, ipc::CommandState::Executing);
  return true;
}

void ScrewCompComponent::finish(bool taken) {
  Pending& p = *pending_;
  if (taken) {
    const std::string text = "joint " + std::to_string(p.joint) + ": compensation table " + p.file + " in use (" +
                             std::to_string(p.entries) + " entries)";
    if (messages_) messages_->post(MessageKind::Text, "screwcomp", text);
    tell_if_longer_than_linuxcnc(p.joint, p.file, p.entries);
    p.reporter->report(p.cmd, ipc::CommandState::Done, text);
  } else {
    p.reporter->report(p.cmd, ipc::CommandState::Rejected,
                       "joint " + std::to_string(p.joint) +
                           ": the servo thread did not take the new table within 2 s (the joint kept moving, or the "
                           "servo thread is not running); the old table stays");
  }
  pending_.reset();
}

void ScrewCompComponent::update(int64_t now_ns) {
  now_ns_ = now_ns;
  if (!pending_) return;
  Pending& p = *pending_;
  ScrewCompensation& t = joints_[static_cast<std::size_t>(p.joint)]->table;
  if (!p.started) {
    p.started = true;
    p.deadline_ns = now_ns + kTakeOverTimeoutNs;
  }
  if (t.switches() != p.switches_before) {
    finish(true);
  } else if (now_ns >= p.deadline_ns) {
    finish(!t.withdraw());
  }
}

void ScrewCompComponent::contribute_status(ipc::Status& status) {
  // Runs before the task controller fills its part: this is the state of
  // the previous task cycle, good enough to refuse a load mid-program.
  program_idle_ = status.task.interp_state == ipc::InterpState::Idle;
}

}  // namespace cnc::comp
