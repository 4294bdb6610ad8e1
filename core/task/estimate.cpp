#include "core/task/estimate.hpp"

#include <algorithm>
#include <deque>
#include <memory>

#include "core/ini/ini_file.hpp"
#include "core/io/io_controller.hpp"
#include "core/motion/motion_controller.hpp"
#include "core/tp/lookahead_planner.hpp"
#include "core/util/strings.hpp"
#include "kinematics/trivkins.hpp"

namespace cnc::estimate {
namespace {

// Stands in for the planner while the motion controller is built: keeps
// the configuration it puts in force (MotionController::apply_limits).
class ConfigCapture final : public tp::TrajectoryPlanner {
 public:
  void set_position(const Pose&) noexcept override {}
  void reset(const Pose&) noexcept override {}
  tp::Result add_line(const Pose&, const tp::SegmentParams&) noexcept override { return tp::Result::NotAllowed; }
  tp::Result add_circle(const Pose&, const std::array<double, 3>&, const std::array<double, 3>&, int,
                        const tp::SegmentParams&) noexcept override {
    return tp::Result::NotAllowed;
  }
  tp::Result add_dwell(double, const tp::SegmentParams&) noexcept override { return tp::Result::NotAllowed; }
  void run_cycle(const tp::CycleInputs&, tp::CycleOutputs&) noexcept override {}
  void pause() noexcept override {}
  void resume() noexcept override {}
  void step() noexcept override {}
  void abort() noexcept override {}
  bool is_done() const noexcept override { return true; }
  bool is_paused() const noexcept override { return false; }
  int queue_depth() const noexcept override { return 0; }
  bool is_queue_full() const noexcept override { return false; }
  void set_config(const tp::PlannerConfig& c) noexcept override { config = c; }
  tp::PlannerConfig config;
};

// trivkins' joint map from [KINS]KINEMATICS ("trivkins coordinates=XYZ"),
// which the configuration's HAL file loads (`loadrt [KINS]KINEMATICS`);
// empty for other kinematics.
std::unique_ptr<kin::TrivKins> trivkins_of(const ini::IniFile& ini, int num_joints) {
  const std::string kins = ini.get_string("KINS", "KINEMATICS", "trivkins");
  const auto words = split_blanks(kins);
  if (words.empty() || words[0] != "trivkins") return nullptr;
  std::string coordinates = std::string("XYZABCUVW").substr(0, static_cast<std::size_t>(std::clamp(num_joints, 1, 9)));
  std::string kinstype = "1";
  for (std::size_t i = 1; i < words.size(); ++i) {
    if (starts_with_icase(words[i], "coordinates=")) coordinates = words[i].substr(12);
    if (starts_with_icase(words[i], "kinstype=")) kinstype = words[i].substr(9);
  }
  try {
    return std::make_unique<kin::TrivKins>(kin::JointMap::parse(coordinates, "trivkins", true),
                                           kin::parse_kinstype(kinstype, "trivkins"));
  } catch (const std::exception& e) {
    ini.fail(ini.find_entry("KINS", "KINEMATICS"), e.what());
  }
}

bool is_segment(motion::Cmd c) {
  return c == motion::Cmd::SetLine || c == motion::Cmd::SetCircle || c == motion::Cmd::SetDwell || c == motion::Cmd::Probe;
}

}  // namespace

Machine load_machine(const std::filesystem::path& ini_path) { return load_machine(ini::IniFile::load(ini_path)); }

Machine load_machine(const ini::IniFile& ini) {
  Machine m;
  m.ini = ini.path();
  const int joints = static_cast<int>(ini.get_int("KINS", "JOINTS", 3, {1, kMaxJoints}));
  const motion::MotionConfig mc = motion::load_motion_config(ini, joints);
  motion::MotionStatus ms;
  if (auto kins = trivkins_of(ini, joints)) {
    if (kins->num_joints() != joints) {
      ini.fail(ini.find_entry("KINS", "KINEMATICS"),
               "trivkins drives " + std::to_string(kins->num_joints()) + " joints but [KINS]JOINTS = " + std::to_string(joints));
    }
    motion::MotionConfig c = mc;
    for (int a = 0; a < kNumAxes; ++a) {
      if (kins->axis_mask() & (1U << a)) c.axes[static_cast<std::size_t>(a)].present = true;
    }
    ConfigCapture capture;
    motion::MotionController controller(c, *kins, capture, nullptr);
    controller.fill_status(ms);
    m.planner = capture.config;
    double q[kMaxJoints] = {};
    for (int j = 0; j < joints; ++j) q[j] = mc.joints[static_cast<std::size_t>(j)].homing.home;
    if (kins->forward(q, m.home) != kin::KinResult::Ok) m.home = Pose{};
    m.kinematics = ini.get_string("KINS", "KINEMATICS", "trivkins");
    m.joint_limits_applied = true;
  } else {
    // Coupled kinematics: the joint limits do not map onto axes.
    uint32_t mask = 0;
    for (int a = 0; a < kNumAxes; ++a) {
      if (mc.axes[static_cast<std::size_t>(a)].present) mask |= 1U << a;
    }
    m.planner = motion::planner_config(mc, mask);
    ms.traj.max_linear_velocity = mc.max_linear_velocity;
    ms.traj.max_linear_acceleration = mc.max_linear_acceleration;
    ms.traj.axis_mask = mask;
    for (int a = 0; a < kNumAxes; ++a) ms.axes[a].velocity_limit = mc.axes[static_cast<std::size_t>(a)].max_velocity;
    m.kinematics = ini.get_string("KINS", "KINEMATICS", "") + " (not trivkins: [AXIS_L] limits only, start at 0)";
  }
  m.canon = task::canon_config(ini, mc, m.planner.axis_mask);
  task::view_limits(ms, m.view);
  m.interp = interp::Config::from_ini(ini);
  m.interp.axis_mask = m.planner.axis_mask;
  m.interp.spindles = std::max(1, mc.spindles);  // motion owns [TRAJ]SPINDLES
  m.python = interp::python_settings(ini);
  // As a preview, not as cncd's task: M99 at the end of the main program
  // ends the estimate after one pass (cncd would run it again for ever),
  // and #<_task> reads 0.
  m.interp.task = false;
  const io::IoConfig io = io::IoConfig::from_ini(ini);
  m.tools = tooltable::ToolTable(io.kind);
  if (!io.tool_table.empty() && std::filesystem::exists(io.tool_table)) {
    m.tools = tooltable::ToolTable::load(io.tool_table, io.kind);
  }
  return m;
}

Moves read_program(const Machine& machine, const std::filesystem::path& program, const Pose& start) {
  Moves out;
  out.start = start;
  tooltable::ToolTable tools = machine.tools;
  task::MachineView view = machine.view;
  view.tools = &tools;
  view.position = start;
  view.tool_in_spindle = tools.spindle().is_empty() ? 0 : tools.spindle().number;
  std::deque<task::Item> items;
  task::TaskCanon canon(machine.canon, items, view);
  canon.set_end_position(start);
  interp::Config config = machine.interp;
  config.script = interp::make_python_host(machine.python);
  interp::Interpreter in(canon, std::move(config));
  tp::Program section;
  section.start = start;
  Pose end = start;
  // The machine comes to rest: what is queued so far is one section.
  const auto rest = [&] {
    if (!section.moves.empty()) out.sections.push_back(std::move(section));
    section = tp::Program{};
    section.start = end;
    view.position = end;
  };
  const auto take_items = [&] {
    for (task::Item& it : items) {
      if (it.kind == task::Item::Kind::Motion) {
        if (!is_segment(it.motion.type)) continue;  // tool offset, outputs with motion: no path
        tp::ProgramMove mv;
        mv.params = it.motion.segment;
        if (it.motion.type == motion::Cmd::SetDwell) {
          mv.kind = tp::ProgramMove::Kind::Dwell;
          mv.seconds = it.motion.value[0];
          mv.end = end;
        } else {
          mv.kind = it.motion.type == motion::Cmd::SetCircle ? tp::ProgramMove::Kind::Circle : tp::ProgramMove::Kind::Line;
          mv.end = it.motion.end;
          mv.center = it.motion.center;
          mv.normal = it.motion.normal;
          mv.turns = it.motion.turns;
          if (it.motion.type == motion::Cmd::Probe) mv.params.type = tp::MotionType::Probe;
          end = mv.end;
        }
        section.moves.push_back(mv);
        ++out.count;
        continue;
      }
      // Everything else the task executes only with motion at rest.
      rest();
      if (it.kind == task::Item::Kind::ToolChange) tools.change_tool(it.i0);
      if (it.kind == task::Item::Kind::ToolNumber) tools.set_spindle_tool(it.i0);
      if (it.kind == task::Item::Kind::ToolSetEntry) tools.update_tool(it.tool);
      view.tool_in_spindle = tools.spindle().is_empty() ? 0 : tools.spindle().number;
    }
    items.clear();
  };
  const auto synch = [&] {
    rest();
    canon.set_end_position(end);
    in.synch();
  };
  try {
    in.init();
    in.open(program);
    for (;;) {
      const interp::Status rs = in.read();
      if (rs == interp::Status::Yield) continue;
      if (rs == interp::Status::SynchRequired) {
        take_items();
        synch();
        continue;
      }
      if (rs == interp::Status::ProgramEnd || rs == interp::Status::EndOfFile) break;
      const int line = in.line();
      const interp::Status st = in.execute();
      if (const std::string e = canon.take_error(); !e.empty()) {
        out.error = program.string() + ":" + std::to_string(line) + ": " + e;
        return out;
      }
      take_items();
      if (st == interp::Status::ProgramEnd) break;
      if (st == interp::Status::ExecuteFinish) synch();
    }
  } catch (const interp::InterpError& e) {
    out.error = (e.file().empty() ? program.string() : e.file()) + ":" + std::to_string(e.line()) + ": " + e.message();
    return out;
  }
  take_items();
  rest();
  out.end = end;
  return out;
}

Result run(const Machine& machine, const Moves& moves, const Options& o) {
  Result r;
  r.moves = moves.count;
  r.end = moves.start;
  if (!moves.error.empty()) {
    r.error = moves.error;
    return r;
  }
  auto planner = tp::make_planner(machine.planner, tp::PlannerThreading::Inline);
  tp::RunOptions ro;
  ro.measure_cpu = o.measure_cpu;
  ro.flush_at_end = o.flush_at_end;
  ro.moves_per_cycle = o.moves_per_cycle;
  if (o.after_cycle) ro.after_cycle = [&o](uint64_t, const tp::CycleOutputs& out) { o.after_cycle(out); };
  double moving = 0, at_feed = 0, feed_ratio = 0;
  r.completed = true;
  for (std::size_t s = 0; s < moves.sections.size(); ++s) {
    const tp::Program& p = moves.sections[s];
    const tp::RunResult rr = tp::run_program(*planner, machine.planner, p, ro);
    tp::StreamStats& st = r.stats;
    st.time_s += rr.stats.time_s;
    r.servo_split += rr.servo_split;
    for (int a = 0; a < kNumAxes; ++a) {
      st.max_v[a] = std::max(st.max_v[a], rr.stats.max_v[a]);
      st.max_a[a] = std::max(st.max_a[a], rr.stats.max_a[a]);
      st.max_j[a] = std::max(st.max_j[a], rr.stats.max_j[a]);
    }
    st.ratio_v = std::max(st.ratio_v, rr.stats.ratio_v);
    st.ratio_a = std::max(st.ratio_a, rr.stats.ratio_a);
    st.ratio_j = std::max(st.ratio_j, rr.stats.ratio_j);
    st.max_deviation = std::max(st.max_deviation, rr.stats.max_deviation);
    st.deviation_ratio = std::max(st.deviation_ratio, rr.stats.deviation_ratio);
    st.end_error = rr.stats.end_error;
    st.samples += rr.stats.samples;
    moving += rr.stats.time_s;
    at_feed += rr.stats.at_feed_fraction * rr.stats.time_s;
    feed_ratio += rr.stats.mean_feed_ratio * rr.stats.time_s;
    r.cycle_ns.insert(r.cycle_ns.end(), rr.cycle_ns.begin(), rr.cycle_ns.end());
    r.add_ns.insert(r.add_ns.end(), rr.add_ns.begin(), rr.add_ns.end());
    r.end = rr.last.position;
    if (!rr.completed) {
      r.completed = false;
      r.error = "section " + std::to_string(s + 1) + " (program line " +
                std::to_string(p.moves.empty() ? 0 : p.moves.front().params.line) + ") did not run to its end";
      break;
    }
  }
  if (moving > 0) {
    r.stats.at_feed_fraction = at_feed / moving;
    r.stats.mean_feed_ratio = feed_ratio / moving;
  }
  r.time_s = r.stats.time_s;
  r.stops = moves.sections.empty() ? 0 : moves.sections.size() - 1;
  return r;
}

Result estimate(const Machine& machine, const std::filesystem::path& program, const Options& o) {
  const Moves moves = read_program(machine, program, o.start.value_or(machine.home));
  return run(machine, moves, o);
}

}  // namespace cnc::estimate
