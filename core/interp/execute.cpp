// Executing one block: LinuxCNC's order (comment, spindle mode, feed mode,
// F, S, T, M codes, G codes, stop codes) and every non-motion conversion.
#include <cmath>
#include <cstdio>

#include "core/ini/ini_file.hpp"
#include "core/util/strings.hpp"

#include "core/interp/impl.hpp"

namespace cnc::interp {

namespace {
double units_per_inch(Units u) { return u == Units::Inch ? 1.0 : (u == Units::Mm ? kMmPerInch : kMmPerInch / 10.0); }
// LinuxCNC's FROM_PROG_LEN factor: program units to millimetres.
double mm_per_unit(Units u) { return u == Units::Inch ? kMmPerInch : (u == Units::Cm ? 10.0 : 1.0); }

std::string_view skip_blanks(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  return s;
}

// "(msg,text)" style prefixes: blanks before the keyword are allowed,
// then the keyword in any case and a comma.
bool comment_prefix(std::string_view c, std::string_view key, std::string_view& rest) {
  c = skip_blanks(c);
  if (c.size() < key.size() + 1) return false;
  if (!cnc::iequals(c.substr(0, key.size()), key) || c[key.size()] != ',') return false;
  rest = c.substr(key.size() + 1);
  return true;
}
}  // namespace

double Interpreter::State::to_program_len(double machine_len) const {
  const double ext = canon.external_length_units();
  if (ext > 0) return (machine_len / ext) / mm_per_unit(units);
  return machine_len * units_per_inch(units) / units_per_inch(canon.machine_length_units());
}

double Interpreter::State::to_machine_len(double program_len) const {
  const double ext = canon.external_length_units();
  if (ext > 0) return (program_len * mm_per_unit(units)) * ext;
  return program_len * units_per_inch(canon.machine_length_units()) / units_per_inch(units);
}

// Rotary axes (A B C) are in degrees whatever the length units.
double Interpreter::State::to_program_axis(int axis, double machine_value) const {
  return axis >= 3 && axis <= 5 ? machine_value : to_program_len(machine_value);
}

double Interpreter::State::to_machine_axis(int axis, double program_value) const {
  return axis >= 3 && axis <= 5 ? program_value : to_machine_len(program_value);
}

void Interpreter::State::canon_init_calls() {
  canon.use_length_units(units);
  Pose g5x{};
  for (int i = 0; i < kNumAxes; ++i) g5x[i] = origin_offset[i];
  canon.set_g5x_offset(origin, g5x);
  canon.set_g92_offset(axis_offset);
  canon.set_xy_rotation(rotation);
  canon.set_feed_reference(FeedReference::Xyz);
}

void Interpreter::State::reset_modal(bool keep_params) {
  if (!keep_params) init_parameters();
  active_spindle = 0;
  pos = Pose{};
  units = config.default_units;
  plane = Plane::XY;
  absolute = true;
  ijk_absolute = false;
  feed_mode = FeedMode::UnitsPerMinute;
  feed = 0;
  speed = 0;
  spindle = Direction::Stopped;
  css = false;
  css_max = 0;
  other_spindles = {};
  mist = flood = false;
  motion_mode = -1;  // G80 until a motion code is given
  origin = round_to_int(params[5220]);
  if (origin < 1 || origin > 9) origin = 1;
  const int base = 5201 + 20 * origin;
  for (int i = 0; i < kNumAxes; ++i) origin_offset[i] = to_program_axis(i, params[static_cast<std::size_t>(base + i)]);
  rotation = params[static_cast<std::size_t>(base + 9)];
  for (int i = 0; i < kNumAxes; ++i) {
    axis_offset[i] = params[5210] != 0.0 ? to_program_axis(i, params[static_cast<std::size_t>(5211 + i)]) : 0.0;
  }
  // Until the first synch the machine is taken to be at its origin, so the
  // program position is minus the stored offsets (as LinuxCNC starts).
  for (int i = 0; i < kNumAxes; ++i) pos[i] = 0.0 - (origin_offset[i] + axis_offset[i]);
  tool_offset = Pose{};
  tool_offset_g = 490;
  control = MotionMode::Continuous;
  tolerance = naive_tolerance = 0;
  retract_old_z = false;  // LinuxCNC starts in G99
  feed_override = speed_override = true;
  adaptive = false;
  feed_hold = true;
  diameter_mode = config.lathe_diameter_mode;
  selected_tool = -1;
  selected_index = 0;  // M6 without T "changes" to the empty index 0
  current_index = 0;
  toolchange_flag = false;
  cutter_side = 400;
  cutter_radius = 0;
  comp_exit_move = false;
  queueing.queue().clear();
  comp_start_valid = false;
  cycle_l = 1;
  frames.clear();
  frames.emplace_back();
  skipping = false;
  synch_pending = false;
  block_ready = false;
}

void Interpreter::State::update_tool_from_canon() {
  tools = canon.tool_table();
  current_index = canon.tool_slot();
}

void Interpreter::State::snapshot_modal(ModalSnapshot& m) const {
  m.valid = true;
  m.units = units;
  m.plane = plane;
  m.absolute = absolute;
  m.ijk_absolute = ijk_absolute;
  m.feed_mode = feed_mode;
  m.feed = feed;
  m.speed = speed;
  m.spindle = spindle;
  m.mist = mist;
  m.flood = flood;
  m.control = control;
  m.tolerance = tolerance;
  m.naive_tolerance = naive_tolerance;
  m.origin = origin;
  m.retract_old_z = retract_old_z;
  m.feed_override = feed_override;
  m.speed_override = speed_override;
}

void Interpreter::State::restore_modal(const ModalSnapshot& m) {
  // The order LinuxCNC 2.9 restores in (M72, M73 at return).
  if (m.units != units) convert_units(m.units);
  if (m.feed_mode != feed_mode) {
    feed_mode = m.feed_mode;
    canon.set_feed_mode(0, feed_mode == FeedMode::UnitsPerRev ? FeedMode::UnitsPerRev : FeedMode::UnitsPerMinute);
  }
  if (m.feed != feed) {
    feed = m.feed;
    canon.set_feed_rate(feed);
  }
  if (m.speed != speed) {
    speed = m.speed;
    canon.set_spindle_speed(0, speed);
  }
  set_distance_mode(m.absolute);
  ijk_absolute = m.ijk_absolute;
  if (m.spindle != spindle) {
    spindle = m.spindle;
    if (spindle == Direction::Clockwise) canon.start_spindle_clockwise(0);
    if (spindle == Direction::CounterClockwise) canon.start_spindle_counterclockwise(0);
    if (spindle == Direction::Stopped) canon.stop_spindle_turning(0);
  }
  if (m.plane != plane) {
    plane = m.plane;
    canon.select_plane(plane);
  }
  if (m.origin != origin) {
    static constexpr int codes[] = {540, 550, 560, 570, 580, 590, 591, 592, 593};
    convert_coordinate_system(codes[m.origin - 1]);
  }
  if (m.control != control || m.tolerance != tolerance || m.naive_tolerance != naive_tolerance) {
    control = m.control;
    tolerance = m.tolerance;
    naive_tolerance = m.naive_tolerance;
    canon.set_motion_control_mode(control, tolerance);
    if (control == MotionMode::Continuous) canon.set_naivecam_tolerance(naive_tolerance);
  }
  if (m.mist != mist || m.flood != flood) {
    if (m.mist) canon.mist_on();
    if (m.flood) canon.flood_on();
    if (!m.mist) canon.mist_off();
    if (!m.flood) canon.flood_off();
    mist = m.mist;
    flood = m.flood;
  }
  retract_old_z = m.retract_old_z;
  if (m.feed_override != feed_override) {
    feed_override = m.feed_override;
    feed_override ? canon.enable_feed_override() : canon.disable_feed_override();
  }
  if (m.speed_override != speed_override) {
    speed_override = m.speed_override;
    speed_override ? canon.enable_speed_override(0) : canon.disable_speed_override(0);
  }
}

namespace {
// The argspec letters of a remap (lower case), without @ > ^.
uint32_t argspec_words(const RemapSpec& r) {
  uint32_t mask = 0;
  for (char ch : r.argspec) {
    const char l = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    if (l >= 'a' && l <= 'z') mask |= 1u << (l - 'a');
  }
  return mask;
}
}  // namespace

// The steps of a block in LinuxCNC's order. A remapped code stops the block
// at its step; it goes on from the next step when the procedure returns.
enum ExecStep : int {
  kStepComment = 1, kStepSpindleMode, kStepFeedMode, kStepFeed, kStepSpeed, kStepTool,
  kStepMIo, kStepMToolChange, kStepMSpindle, kStepMState, kStepMCoolant, kStepMOverride, kStepMUser,
  kStepG, kStepMotion, kStepStop, kStepEnd
};

Status Interpreter::State::execute_block() {
  Status st = Status::Ok;
  const int first = exec_step;
  exec_step = 0;
  if (first == 0) {
    check_remap_args();
    if (block.g[kGNonModal] == 530) {
      const int m = block.g[kGMotion] != -1 ? block.g[kGMotion] : motion_mode;
      if (m != 0 && m != 10) fail("Must use g0 or g1 with g53");
      if (block.g[kGDistance] == 910 || (block.g[kGDistance] == -1 && !absolute)) fail("Cannot use g53 incremental");
    }
    // Words a remapped code takes (its argspec) are used by it.
    uint32_t taken = 0;
    for (int step = kStepComment; step < kStepEnd; ++step) {
      if (const RemapSpec* r = remap_at_step(step)) taken |= argspec_words(*r);
    }
    const uint32_t has = block.has;
    block.has &= ~taken;
    check_other_words();
    block.has = has;
  }
  canon.begin_block(block.line, block.n_number, block.n_text);
  n_number = block.n_number;
  for (int step = first == 0 ? int{kStepComment} : first; step < kStepEnd; ++step) {
    // The procedure carries the code out; the rest of the block runs after it.
    if (const RemapSpec* r = remap_at_step(step)) return start_remap(*r, step, st);
    execute_step(step, st);
  }
  return st;
}

void Interpreter::State::execute_step(int step, Status& st) {
  switch (step) {
    case kStepComment:
      if (block.has_comment) convert_comment();
      if (block.has_py) run_script(block.py_code);
      break;
    case kStepSpindleMode:
      if (block.g[kGSpindleMode] != -1) convert_spindle_mode(block.g[kGSpindleMode]);
      break;
    case kStepFeedMode:
      if (block.g[kGFeedMode] != -1) convert_feed_mode(block.g[kGFeedMode]);
      break;
    case kStepFeed:
      if (block.has_word('f') && feed_mode != FeedMode::InverseTime) {
        feed = block.get('f');
        canon.set_feed_rate(feed);
      }
      break;
    case kStepSpeed:
      if (block.has_word('s')) {
        for (int k : chosen_spindles("Spindle speed command")) set_speed(k, block.get('s'));
      }
      break;
    case kStepTool:
      if (block.has_word('t')) convert_tool_select();
      break;
    case kStepMIo: convert_m(kMIo, st); break;
    case kStepMToolChange: convert_m(kMToolChange, st); break;
    case kStepMSpindle: convert_m(kMSpindle, st); break;
    case kStepMState: convert_m(kMState, st); break;
    case kStepMCoolant: convert_m(kMCoolant, st); break;
    case kStepMOverride: convert_m(kMOverride, st); break;
    case kStepMUser: convert_m(kMUser, st); break;
    case kStepG: convert_g(); break;
    case kStepMotion: convert_g_motion(st); break;
    case kStepStop:
      if (block.m[kMStop] != -1) convert_stop(st);
      break;
    default: break;
  }
}

// ---------------------------------------------------------------- REMAP

const RemapSpec* Interpreter::State::find_remap(char letter, int code, bool active_too) const {
  for (const RemapSpec& r : config.remaps) {
    if (r.letter != letter || r.code != code) continue;
    if (!active_too) {
      // Inside its own procedure a remapped code is the built-in one.
      for (const Frame& f : frames) {
        if (f.remap && f.remap->spec == &r) return nullptr;
      }
      for (const auto& rc : python_remaps) {
        if (rc->spec == &r) return nullptr;
      }
    }
    return &r;
  }
  return nullptr;
}

const RemapSpec* Interpreter::State::remap_at_step(int step) const {
  if (config.remaps.empty()) return nullptr;
  auto m_at = [&](int group) { return block.m[group] != -1 ? find_remap('m', block.m[group]) : nullptr; };
  switch (step) {
    case kStepFeed: return block.has_word('f') ? find_remap('f', 0) : nullptr;
    case kStepSpeed: return block.has_word('s') ? find_remap('s', 0) : nullptr;
    case kStepTool: return block.has_word('t') ? find_remap('t', 0) : nullptr;
    case kStepMIo: return m_at(kMIo);
    case kStepMToolChange: return m_at(kMToolChange);
    case kStepMSpindle: return m_at(kMSpindle);
    case kStepMCoolant: return m_at(kMCoolant);
    case kStepMOverride: return m_at(kMOverride);
    case kStepMUser: return m_at(kMUser);
    case kStepMotion: return block.g[kGMotion] != -1 ? find_remap('g', block.g[kGMotion]) : nullptr;
    case kStepStop: return m_at(kMStop);
    default: return nullptr;
  }
}

int Interpreter::State::remap_level() const {
  int n = static_cast<int>(python_remaps.size());
  for (const Frame& f : frames) n += f.remap ? 1 : 0;
  return n;
}


// Required words (upper case in argspec), a feed (>) and a speed (^) of
// every remapped code of the block, before anything of it runs.
void Interpreter::State::check_remap_args() {
  if (config.remaps.empty()) return;
  for (int step = kStepComment; step < kStepEnd; ++step) {
    const RemapSpec* r = remap_at_step(step);
    if (r == nullptr) continue;
    std::string missing;
    for (char ch : r->argspec) {
      if (ch < 'A' || ch > 'Z') continue;
      if (!block.has_word(static_cast<char>(ch + 32))) missing += (missing.empty() ? "" : ",") + std::string(1, ch);
    }
    if (!missing.empty()) {
      line_text = "O <" + r->ngc + "> call ";
      fail("user-defined " + r->name() + ": missing: " + missing);
    }
    if (r->argspec.find('>') != std::string::npos && !((block.has_word('f') ? block.get('f') : feed) > 0)) {
      fail("user-defined " + r->name() + ": needs a feed rate greater than 0 (F)");
    }
    if (r->argspec.find('^') != std::string::npos && !((block.has_word('s') ? block.get('s') : speed) > 0)) {
      fail("user-defined " + r->name() + ": needs a spindle speed greater than 0 (S)");
    }
  }
}

bool Interpreter::State::python_stage(StageKind kind, const std::shared_ptr<RemapCall>& rc, bool resume) {
  const RemapSpec& spec = *rc->spec;
  const std::string& function = kind == StageKind::Prolog ? spec.prolog : kind == StageKind::Body ? spec.python : spec.epilog;
  if (!config.script) {
    fail(spec.name() + ": its Python procedure " + function +
         " needs the interpreter's embedded Python, which this program does not have");
  }
  ScriptHost& host = *config.script;
  const std::size_t suspended = host.suspended_remaps();
  ScriptHost::RemapOutcome out;
  try {
    out = resume ? host.resume_remap() : host.call_remap(function, rc->words);
  } catch (const std::runtime_error& e) {
    out.error = e.what();
    out.waits = false;
  }
  if (!out.error.empty()) {
    // LinuxCNC shows the call it made (an NGC body's epilog: the endsub)
    if (kind != StageKind::Epilog || !spec.python.empty()) {
      line_text = "O <" + (spec.python.empty() ? spec.ngc : spec.python) + "> call ";
    }
    fail(out.error);
  }
  if (out.waits && script_line_depth > 0) {
    // The script that ran self.execute() is on the stack below: it cannot
    // be left until the machine caught up.
    host.drop_suspended_remaps(resume ? suspended - 1 : suspended);
    fail(spec.name() + ": " + function +
         " waits for the machine (yield INTERP_EXECUTE_FINISH) inside self.execute(), which runs its line to the "
         "end: a procedure that waits cannot be run from a script");
  }
  return out.waits;
}

Status Interpreter::State::run_stage(PendingStage p) {
  for (;;) {
    if (python_stage(p.kind, p.rc, p.resume)) {
      // execute() resumes it after the machine caught up (read() reads nothing till then)
      p.resume = true;
      stage = std::move(p);
      return Status::ExecuteFinish;
    }
    p.resume = false;
    const RemapSpec& spec = *p.rc->spec;
    switch (p.kind) {
      case StageKind::Prolog:
        if (!spec.python.empty()) {
          p.kind = StageKind::Body;
          continue;
        }
        {
          // The prolog ran in the body's call frame: what it set in
          // self.params are the body's locals.
          auto locals = std::move(frames.back().locals);
          frames.pop_back();
          call_remap_stage(p.rc);
          for (auto& [n, v] : locals) frame().locals[n] = v;
        }
        return Status::Ok;
      case StageKind::Body:
        if (spec.epilog_python) {
          p.kind = StageKind::Epilog;
          continue;
        }
        break;
      case StageKind::Epilog:
        if (spec.python.empty()) {
          // an NGC body's epilog, met at its endsub: now the return
          do_return(p.has_value, p.value);
          if (!resume_block) return Status::Ok;
          resume_block = false;
          return execute_block();
        }
        break;
      case StageKind::None: return Status::Ok;
    }
    // A Python body (and its epilog) ended: the block goes on after it.
    python_remaps.pop_back();
    block = p.rc->block;
    exec_step = p.rc->resume_step;
    return execute_block();
  }
}

Status Interpreter::State::execute_ready() {
  if (stage.kind == StageKind::None) return execute_block();
  PendingStage p = std::move(stage);
  stage = {};
  return run_stage(std::move(p));
}

void Interpreter::State::drop_stages() {
  stage = {};
  python_remaps.clear();
  if (config.script) config.script->drop_suspended_remaps(0);
}

Status Interpreter::State::start_remap(const RemapSpec& spec, int step, Status st) {
  auto rc = std::make_shared<RemapCall>();
  rc->spec = &spec;
  rc->seq = ++remap_seq;
  rc->block = block;
  rc->resume_step = step + 1;
  rc->line = current_line;
  rc->file = current_file;
  rc->text = line_text;
  const bool positional = spec.argspec.find('@') != std::string::npos;
  for (char ch : spec.argspec) {
    const char l = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    if (l < 'a' || l > 'z' || !block.has_word(l)) continue;
    if (positional) {
      rc->positional.push_back(block.get(l));
    } else {
      rc->named.emplace_back(std::string(1, l), block.get(l));
    }
  }
  for (char ch : spec.argspec) {
    const char l = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    if (l >= 'a' && l <= 'z' && block.has_word(l)) rc->words.emplace_back(std::string(1, l), block.get(l));
  }
  // What an earlier step of the block needs (the machine to catch up) stays.
  const auto merged = [st](Status s) { return st == Status::ExecuteFinish && s == Status::Ok ? st : s; };
  if (!spec.python.empty()) {
    // A Python body: prolog, body and epilog run now, inside the block
    python_remaps.push_back(rc);
    return merged(run_stage({spec.prolog_python ? StageKind::Prolog : StageKind::Body, false, rc}));
  }
  rc->stage = spec.prolog.empty() || spec.prolog_python ? 1 : 0;
  if (spec.prolog_python) {
    // A Python prolog runs in the body's call, before the body is looked
    // for (as in LinuxCNC): what it sets in self.params become the body's
    // local parameters.
    Frame call;
    call.sub_name = spec.ngc;
    call.remap = rc;
    // Left without a return (an error, unwind()): reading goes on where it is.
    call.file_depth = static_cast<int>(files.size());
    if (!files.empty()) {
      call.return_offset = files.back().reader->offset();
      call.return_line = files.back().reader->line_number();
    }
    call.saved_args = {};
    for (int k = 0; k < 30; ++k) call.saved_args[static_cast<std::size_t>(k)] = params[static_cast<std::size_t>(k + 1)];
    for (const auto& [n, v] : rc->named) call.locals[n] = v;
    frames.push_back(std::move(call));
    return merged(run_stage({StageKind::Prolog, false, rc}));
  }
  call_remap_stage(rc);
  return st;
}

void Interpreter::State::call_remap_stage(const std::shared_ptr<RemapCall>& rc) {
  const RemapSpec& spec = *rc->spec;
  const std::string& name = rc->stage == 0 ? spec.prolog : rc->stage == 1 ? spec.ngc : spec.epilog;
  block.o_name = name;
  block.call_args = rc->positional;
  do_call();
  frame().remap = rc;
  for (const auto& [n, v] : rc->named) frame().locals[n] = v;
}

// The procedure of stage rc->stage returned: the next one is called, or the
// block is handed back to be finished. True when the block goes on.
bool Interpreter::State::remap_returned(const std::shared_ptr<RemapCall>& rc) {
  const RemapSpec& spec = *rc->spec;
  int next = rc->stage + 1;
  if (next == 2 && (spec.epilog.empty() || rc->epilog_done)) next = 3;
  if (next <= 2) {
    rc->stage = next;
    call_remap_stage(rc);
    return false;
  }
  block = rc->block;
  exec_step = rc->resume_step;
  current_line = rc->line;
  current_file = rc->file;
  line_text = rc->text;
  resume_block = true;
  return true;
}

// Words no code of the block uses are errors, as in LinuxCNC.
void Interpreter::State::check_other_words() const {
  const bool axes = block.any_axis(config.axis_mask) || block.has_polar_r || block.has_polar_a;
  const int mg = block.g[kGMotion] != -1 ? block.g[kGMotion] : (axes ? motion_mode : -1);
  const int g0 = block.g[kGNonModal];
  const int m_io = block.m[kMIo];
  const bool user_m = block.m[kMUser] != -1;
  const bool cycle = mg == 730 || mg == 740 || (mg >= 810 && mg <= 890);
  const bool g7x = mg == 700 || mg == 710 || mg == 711 || mg == 712 || mg == 720 || mg == 721 || mg == 722;
  const bool g71_72 = g7x && mg != 700;
  auto motion_in = [&](std::initializer_list<int> codes) {
    for (int c : codes) {
      if (mg == c) return true;
    }
    return false;
  };
  if (g0 != -1 && g0 != 40 && g0 != 530 && g0 != 281 && g0 != 301 && g0 != 921 && g0 != 922 && g0 != 923 &&
      block.g[kGMotion] != -1 && block.g[kGMotion] != 800 && axes) {
    fail("Cannot use two g codes that both use axis values");
  }
  const int cutter = block.g[kGCutter];
  if (block.has_word('d') && !(cutter == 410 || cutter == 411 || cutter == 420 || cutter == 421) &&
      block.g[kGSpindleMode] != 960 && !g7x) {
    fail("D word with no G41, G41.1, G42, G42.1, G71, G71.1, G71.2 or G96 to use it");
  }
  if ((cutter == 411 || cutter == 421) && !block.has_word('d')) fail(cutter == 411 ? "G41.1 with no D word" : "G42.1 with no D word");
  if (block.has_word('e') && mg != 760 && mg != 700 && m_io != 66 && m_io != 67 && m_io != 68) {
    fail("E word with no G70, G76, M66, M67 or M68 to use it");
  }
  const int tlo = block.g[kGToolOffset];
  if (block.has_word('h') && tlo != 430 && tlo != 432 && mg != 760) fail("H word with no G43 or G76 to use it");
  if (block.has_word('i') && !motion_in({20, 30, 50, 51, 331, 760, 870}) && !g71_72 && g0 != 100) {
    fail("I word with no G2, G3, G5, G5.1, G10, G33.1, G76, or G87 to use it");
  }
  if (block.has_word('j') && !motion_in({20, 30, 50, 51, 760, 870}) && g0 != 100) {
    fail("J word with no G2, G3, G5, G5.1, G10, G76 or G87 to use it");
  }
  if (block.has_word('k') && !motion_in({20, 30, 330, 331, 760, 870})) {
    fail("K word with no G2, G3, G33, G33.1, G76, or G87 to use it");
  }
  if (block.has_word('l') && g0 != 100 && !cycle && cutter != 411 && cutter != 421 && m_io != 66 && mg != 760 &&
      mg != 52 && block.m[kMStop] != 98) {
    fail("L word with no G10, cutter compensation, canned cycle, digital/analog input, M98 or NURBS code");
  }
  const int ov = block.m[kMOverride];
  if (block.has_word('p') && !motion_in({20, 30, 50, 52, 700, 740, 760, 820, 840, 860, 880, 890}) && g0 != 40 && g0 != 100 &&
      block.g[kGControl] != 640 && !(ov >= 50 && ov <= 53) && !(m_io >= 62 && m_io <= 66) && !user_m &&
      block.m[kMSpindle] != 19 && block.m[kMStop] != 98) {
    fail("P word with no G2 G3 G4 G10 G64 G5 G5.2 G76 G82 G86 G88 G89 or M50 M51 M52 M53 M62 M63 M64 M65 M66 M98 or user M code to use it");
  }
  if (block.has_word('q') && !motion_in({50, 730, 760, 830}) && !g7x && g0 != 100 && block.g[kGControl] != 640 &&
      block.m[kMSpindle] != 19 && m_io != 66 && m_io != 67 && m_io != 68 && !user_m && block.m[kMToolChange] != 61) {
    fail("Q word with no G5, G10, G64, G73, G76, G83, M19, M66, M67, M68 or user M code that uses it");
  }
  if (block.has_word('r') && !motion_in({20, 30, 760}) && !cycle && !g71_72 && g0 != 100 && block.m[kMSpindle] != 19) {
    fail("R word with no g code that uses it");
  }
  if (block.has_dollar && !block.has_word('s')) {
    const int sp = block.m[kMSpindle];
    const int fm = block.g[kGFeedMode];
    const int sm = block.g[kGSpindleMode];
    if (sp != 3 && sp != 4 && sp != 5 && sp != 19 && block.m[kMOverride] != 51 && !motion_in({330, 331, 760}) &&
        fm != 950 && sm != 960 && sm != 970) {
      fail("$ (spindle selection) word with no M3, M4, M5, M19, M51, G33, G33.1, G76, G95, G96 or G97 to use it");
    }
  }
  if (block.m[kMSpindle] == 19 && block.has_word('p')) {
    const double p = block.get('p');
    if (std::fabs(round_to_int(p) - p) > 0.001) fail("P value not an integer with M19 G2 or G3");
    if (round_to_int(p) < 0 || round_to_int(p) > 2) fail("P value must be 0,1,or 2 with M19");
  }
  if (block.m[kMSpindle] == 19 && block.has_word('r') && (block.get('r') > 360.0 || block.get('r') < 0.0)) {
    fail("R value must be within 0..360 with M19");
  }
}

void Interpreter::State::run_script(const std::string& code) {
  if (!config.script) return;  // no scripts configured: a comment like any other
  try {
    config.script->run_statement(code);
  } catch (const std::runtime_error& e) {
    fail(std::string("py,") + code + ": " + e.what());
  }
}

void Interpreter::State::convert_comment() {
  std::string_view c = block.comment;
  std::string_view rest;
  if (comment_prefix(c, "msg", rest)) {
    canon.message(rest);
  } else if (comment_prefix(c, "debug", rest)) {
    const std::string text = substitute_params(rest);
    if (params[5599] > 0.0) canon.message(text);  // #5599: DEBUG output on (1 at start)
  } else if (comment_prefix(c, "abort", rest)) {
    fail(substitute_params(rest));  // the program stops with the text as its error
  } else if (comment_prefix(c, "print", rest)) {
    canon.print(substitute_params(rest));
  } else if (comment_prefix(c, "logopen", rest)) {
    canon.log_open(rest, false);
  } else if (comment_prefix(c, "logappend", rest)) {
    canon.log_open(rest, true);
  } else if (comment_prefix(c, "log", rest)) {
    canon.log(substitute_params(rest));
  } else if (cnc::iequals(cnc::trim(c), "logclose")) {
    canon.log_close();
  } else if (config.script && comment_prefix(c, "py", rest)) {
    run_script(std::string(rest));
  } else {
    canon.comment(skip_blanks(c));  // LinuxCNC drops the leading blanks
  }
}

void Interpreter::State::convert_spindle_mode(int g) {
  active_spindle = block.has_dollar && block.dollar >= 0 ? chosen_spindle("Spindle Mode command") : 0;
  for (int k : chosen_spindles("Spindle Mode command")) {
    bool& mode = k == 0 ? css : other_spindles[static_cast<std::size_t>(k)].css;
    double& max = k == 0 ? css_max : other_spindles[static_cast<std::size_t>(k)].css_max;
    if (g == 960) {
      mode = true;
      max = block.has_word('d') ? block.get('d') : 1e30;
      if (!block.has_word('s')) fail("S word missing with G96");
      canon.set_spindle_mode(k, max);
    } else {
      mode = false;
      canon.set_spindle_mode(k, 0);
    }
  }
}

std::vector<int> Interpreter::State::chosen_spindles(const char* what, bool minus_one_allowed) const {
  const int n = config.spindles;
  if (block.dollar == -1 && !block.has_dollar) return {0};
  if (block.dollar == -1 && minus_one_allowed) {
    std::vector<int> all;
    for (int k = 0; k < n; ++k) all.push_back(k);
    return all;
  }
  if (block.dollar < 0 || block.dollar >= n) {
    fail(std::string("Invalid spindle ($) number ") + std::to_string(block.dollar) + " in " + what + ": the machine has " +
         (n == 1 ? std::string("spindle 0") : "spindles 0-" + std::to_string(n - 1)) + " ([TRAJ]SPINDLES), $-1 is all");
  }
  return {block.dollar};
}

void Interpreter::State::set_speed(int k, double rpm) {
  if (k == 0) {
    speed = rpm;
  } else {
    other_spindles[static_cast<std::size_t>(k)].speed = rpm;
  }
  canon.set_spindle_speed(k, rpm);
}

void Interpreter::State::set_direction(int k, Direction d) {
  if (d == Direction::Clockwise) canon.start_spindle_clockwise(k);
  if (d == Direction::CounterClockwise) canon.start_spindle_counterclockwise(k);
  if (d == Direction::Stopped) canon.stop_spindle_turning(k);
  if (k == 0) {
    spindle = d;
  } else {
    other_spindles[static_cast<std::size_t>(k)].dir = d;
  }
}

void Interpreter::State::convert_feed_mode(int g) {
  active_spindle = block.has_dollar ? chosen_spindle("Spindle Feed command") : 0;
  if (g == 930) {
    if (config.linuxcnc_comments) canon.comment("interpreter: feed mode set to inverse time");
    feed_mode = FeedMode::InverseTime;
    canon.set_feed_mode(0, FeedMode::UnitsPerMinute);
  } else if (g == 940) {
    if (config.linuxcnc_comments) canon.comment("interpreter: feed mode set to units per minute");
    feed_mode = FeedMode::UnitsPerMinute;
    canon.set_feed_mode(0, FeedMode::UnitsPerMinute);
    feed = 0;
    canon.set_feed_rate(0);
  } else {
    if (config.linuxcnc_comments) canon.comment("interpreter: feed mode set to units per revolution");
    feed_mode = FeedMode::UnitsPerRev;
    canon.set_feed_mode(active_spindle, FeedMode::UnitsPerRev);
    feed = 0;
    canon.set_feed_rate(0);
  }
}

void Interpreter::State::convert_tool_select() {
  const int t = static_cast<int>(block.get('t'));
  int index = -1;
  if (const auto i = tools.find_tool(t)) {
    index = *i;
  } else if (tools.is_random() && tools.spindle().number == t) {
    index = 0;
  } else if (t == 0 && !tools.is_random()) {
    index = 0;
  } else {
    char buf[80];
    std::snprintf(buf, sizeof buf, "Requested tool %d not found in the tool table", t);
    fail(buf);
  }
  canon.select_tool(t);
  selected_tool = t;
  selected_index = index;
}

void Interpreter::State::convert_tool_change(Status& st) {
  if (block.m[kMToolChange] == 6) {
    if (cutter_side != 400) fail("Cannot change tools with cutter radius compensation on");
    if (selected_index < 0) fail("Need tool prepared -Txx- for toolchange");
    canon.start_change();
    if (!config.tool_change_with_spindle_on) {
      canon.stop_spindle_turning(0);
      spindle = Direction::Stopped;
    }
    canon.change_tool(selected_index);
    current_index = selected_index;
    toolchange_flag = true;
    tools.change_tool(selected_index);
    st = Status::ExecuteFinish;
    return;
  }
  // M61 Q
  if (!block.has_word('q') || block.get('q') < 0) fail("Need non-negative Q-word to specify tool number with M61");
  const int t = static_cast<int>(round_to_int(block.get('q')));
  int index = 0;
  if (t != 0 || tools.is_random()) {
    const auto i = tools.find_tool(t);
    if (!i) {
      char buf[80];
      std::snprintf(buf, sizeof buf, "Requested tool %d not found in the tool table", t);
      fail(buf);
    }
    index = *i;
  }
  canon.change_tool_number(index);
  current_index = index;
  // Manual 3.24.3.5: the spindle now holds that tool (M61 Q0: none).
  tools.set_spindle_tool(index);
  st = Status::ExecuteFinish;
}

// One modal group's M code (LinuxCNC's order is the caller's: 5, 6, 7, 3, 8, 9, 10).
void Interpreter::State::convert_m(int group, Status& st) {
  const int io = group == kMIo ? block.m[kMIo] : -1;
  if (io != -1) {
    if ((io >= 62 && io <= 65) && (!block.has_word('p') || block.get('p') < 0)) {
      fail("No valid P word with M" + std::to_string(io));
    }
    const int p = static_cast<int>(round_to_int(block.get('p')));
    switch (io) {
      case 62:
        if (cutter_side != 400) fail("Cannot set motion digital output with cutter radius compensation on");
        canon.set_motion_output_bit(p);
        break;
      case 63:
        if (cutter_side != 400) fail("Cannot set motion digital output with cutter radius compensation on");
        canon.clear_motion_output_bit(p);
        break;
      case 64: canon.set_aux_output_bit(p); break;
      case 65: canon.clear_aux_output_bit(p); break;
      case 66: {
        const bool has_p = block.has_word('p') && block.get('p') >= 0;
        const bool has_e = block.has_word('e') && block.get('e') >= 0;
        if (has_p && has_e) fail("Invalid to select both a digital and an analog input with M66");
        if (!has_p && !has_e) fail("Need to have either a valid P or a valid E word with M66");
        const int type = block.has_word('l') ? static_cast<int>(block.get('l')) : 0;
        if (type < 0 || type > 4) fail("Unknown wait type");
        const double timeout = block.has_word('q') ? block.get('q') : 0.0;
        if (type != 0 && timeout == 0) fail("Zero timeout with wait type != immediate return");
        if (has_e && type != 0) fail("Can't select analog input with wait type != immediate return");
        if (cutter_side != 400) {
          fail(has_p ? "Cannot wait for digital input with cutter radius compensation on"
                     : "Cannot wait for analog input with cutter radius compensation on");
        }
        const int index = static_cast<int>(round_to_int(has_p ? block.get('p') : block.get('e')));
        canon.wait_input(index, has_p, static_cast<WaitType>(type), timeout);
        st = Status::ExecuteFinish;
        break;
      }
      case 67:
      case 68: {
        if (!block.has_word('e') || block.get('e') < 0) fail(io == 67 ? "Invalid analog index with M67" : "Invalid analog index with M68");
        const int e = static_cast<int>(round_to_int(block.get('e')));
        const double q = block.get('q');
        if (io == 67) {
          if (cutter_side != 400) fail("Cannot set motion analog output with cutter radius compensation on");
          canon.set_motion_output_value(e, q);
        } else {
          canon.set_aux_output_value(e, q);
        }
        break;
      }
      default: break;
    }
  }
  if (group == kMToolChange && block.m[kMToolChange] != -1) convert_tool_change(st);
  switch (group == kMSpindle ? block.m[kMSpindle] : -1) {
    case 3:
      for (int k : chosen_spindles("M3")) set_direction(k, Direction::Clockwise);
      break;
    case 4:
      for (int k : chosen_spindles("M4")) set_direction(k, Direction::CounterClockwise);
      break;
    case 5:
      for (int k : chosen_spindles("M5")) set_direction(k, Direction::Stopped);
      break;
    case 19: {
      // As LinuxCNC 2.9: the angle is R plus [RS274NGC]ORIENT_OFFSET; without
      // R and P nothing is oriented (only Q waits); Q waits for the spindle.
      const int k = chosen_spindles("M19", false).front();
      if (k == 0) {
        spindle = Direction::Stopped;
      } else {
        other_spindles[static_cast<std::size_t>(k)].dir = Direction::Stopped;
      }
      if (block.has_word('r') || block.has_word('p')) {
        const double r = (block.has_word('r') ? block.get('r') : 0.0) + config.orient_offset;
        canon.orient_spindle(k, r, block.has_word('p') ? round_to_int(block.get('p')) : 0);
      }
      if (block.has_word('q')) {
        if (block.get('q') <= 0.0) fail("Q word with M19 requires a value > 0");
        canon.wait_spindle_orient_complete(k, block.get('q'));
      }
      break;
    }
    default: break;
  }
  switch (group == kMState ? block.m[kMState] : -1) {
    // As LinuxCNC: one saved context per call level; M73 also restores it
    // when the subroutine returns.
    case 70: snapshot_modal(frame().saved_modal); break;
    case 71: frame().saved_modal.valid = false; break;
    case 72:
      if (!frame().saved_modal.valid) fail("Cannot restore context from invalid stack frame - missing M70/M73?");
      restore_modal(frame().saved_modal);
      break;
    case 73:
      snapshot_modal(frame().saved_modal);
      if (frames.size() > 1) frame().restore_on_return = true;
      break;
    default: break;
  }
  switch (group == kMCoolant ? block.m[kMCoolant] : -1) {
    case 7:
      canon.mist_on();
      mist = true;
      break;
    case 8:
      canon.flood_on();
      flood = true;
      break;
    case 9:
      canon.mist_off();
      mist = false;
      canon.flood_off();
      flood = false;
      break;
    default: break;
  }
  const int ov = group == kMOverride ? block.m[kMOverride] : -1;
  if (ov != -1 && cutter_side != 400) {
    fail(ov == 48 || ov == 50 || ov == 51 ? "Cannot enable overrides with cutter radius compensation on"
                                          : "Cannot disable overrides with cutter radius compensation on");
  }
  const bool p_on = !block.has_word('p') || block.get('p') != 0.0;
  switch (ov) {
    case 48:
      canon.enable_feed_override();
      for (int k = 0; k < config.spindles; ++k) canon.enable_speed_override(k);
      feed_override = speed_override = true;
      break;
    case 49:
      canon.disable_feed_override();
      for (int k = 0; k < config.spindles; ++k) canon.disable_speed_override(k);
      feed_override = speed_override = false;
      break;
    case 50:
      p_on ? canon.enable_feed_override() : canon.disable_feed_override();
      feed_override = p_on;
      break;
    case 51: {
      // every spindle, or the one $ names (LinuxCNC refuses $0 here; a
      // slip of its check, spindle 0 is a spindle like the others)
      const int only = block.has_dollar ? chosen_spindle("M51 command") : -1;
      for (int k = 0; k < config.spindles; ++k) {
        if (only != -1 && k != only) continue;
        p_on ? canon.enable_speed_override(k) : canon.disable_speed_override(k);
      }
      if (only <= 0) speed_override = p_on;
      break;
    }
    case 52:
      p_on ? canon.enable_adaptive_feed() : canon.disable_adaptive_feed();
      adaptive = p_on;
      break;
    case 53:
      p_on ? canon.enable_feed_hold() : canon.disable_feed_hold();
      feed_hold = p_on;
      break;
    default: break;
  }
  const int user = group == kMUser ? block.m[kMUser] : -1;
  if (user != -1) {
    bool known = false;
    for (const auto& dir : config.user_m_path) {
      char name[8];
      std::snprintf(name, sizeof name, "M%d", user);
      std::error_code ec;
      if (std::filesystem::exists(dir / name, ec)) known = true;
    }
    if (!known) fail("Unknown m code used: M" + std::to_string(user));
    canon.user_m_code(user, block.get('p'), block.get('q'));
  }
}

void Interpreter::State::set_distance_mode(bool abs) {
  if (abs != absolute && config.linuxcnc_comments) {
    canon.comment(abs ? "interpreter: distance mode changed to absolute" : "interpreter: distance mode changed to incremental");
  }
  absolute = abs;
}

void Interpreter::State::convert_dwell() {
  if (!block.has_word('p')) fail("Dwell time missing with g4");
  canon.dwell(block.get('p'));
}

void Interpreter::State::convert_plane(int g) {
  if (cutter_side != 400 && g != 170 && g != 180 && g != 190) fail("Cannot change planes with cutter radius compensation on");
  if (cutter_side != 400 && g == 190) fail("Cannot use XZ or YZ plane with cutter radius compensation on");
  switch (g) {
    case 170: plane = Plane::XY; break;
    case 180: plane = Plane::XZ; break;
    case 190: plane = Plane::YZ; break;
    case 171: plane = Plane::UV; break;
    case 181: plane = Plane::UW; break;
    case 191: plane = Plane::VW; break;
    default: break;
  }
  canon.select_plane(plane);
}

void Interpreter::State::convert_units(Units u) {
  if (cutter_side != 400) fail("Cannot change units with cutter radius compensation on");
  if (u != units) {
    const double k = units_per_inch(u) / units_per_inch(units);
    for (int i = 0; i < kNumAxes; ++i) {
      if (i >= 3 && i <= 5) continue;  // rotary axes keep degrees
      pos[i] *= k;
      origin_offset[i] *= k;
      axis_offset[i] *= k;
      tool_offset[i] *= k;
    }
    // The feed rate stays the number programmed: F is read in the units in
    // force when it is used (LinuxCNC's #<_feed> after G20/G21).
    cycle_r *= k;
    cycle_z *= k;
    cycle_cc *= k;
    units = u;
  }
  canon.use_length_units(u);
}

void Interpreter::State::convert_cutter_comp(int g) {
  if (g == 400) {
    if (cutter_side != 400) {
      comp_flush();
      // The next move must be straight, unless compensation never moved
      // (a zero radius or no move yet: LinuxCNC 2.9 alike). From here the
      // position is the programmed one (LinuxCNC sets its current point to
      // the programmed point): axes the exit move does not name stay there,
      // and a tool length offset change before it shifts it.
      comp_exit_move = cutter_radius > 0 && !cutter_first_move;
      if (comp_exit_move) pos = comp_program_pos;
    }
    if (config.linuxcnc_comments) canon.comment("interpreter: cutter radius compensation off");
    cutter_side = 400;
    return;
  }
  if (cutter_side != 400) fail("Cannot turn cutter radius comp on when on");
  if (plane != Plane::XY && plane != Plane::XZ) fail("Cutter radius compensation allowed only in XY, XZ planes");
  double radius = 0;
  int orientation = 0;
  if (g == 411 || g == 421) {
    radius = block.get('d') / 2.0;
    if (block.has_word('l') && plane != Plane::XZ) fail(g == 411 ? "G41.1 with L word, but plane is not G18" : "G42.1 with L word, but plane is not G18");
    orientation = block.has_word('l') ? static_cast<int>(block.get('l')) : 0;
  } else {
    int index = 0;
    if (block.has_word('d')) {
      const double d = block.get('d');
      if (d < 0) fail("Negative d word tool radius index used");
      const int t = static_cast<int>(round_to_int(d));
      // Manual 3.24.3.6: D names a tool number; D0 or no D: the spindle.
      if (t != 0) {
        const auto i = tools.find_tool_anywhere(t);
        if (!i) {
          char buf[80];
          std::snprintf(buf, sizeof buf, "Requested tool %d not found in the tool table", t);
          fail(buf);
        }
        index = *i;
      }
    }
    radius = to_program_len(tools.at(index).diameter) / 2.0;
    orientation = tools.at(index).orientation;
    // A lathe tool's orientation only has a meaning in the lathe plane.
    if (plane != Plane::XZ && orientation != 0 && orientation != 9) {
      fail(g == 410 ? "G41 with lathe tool, but plane is not G18" : "G42 with lathe tool, but plane is not G18");
    }
  }
  if (radius < 0) {
    radius = -radius;
    g = (g == 410 || g == 411) ? 420 : 410;
  }
  cutter_side = (g == 410 || g == 411) ? 410 : 420;
  cutter_radius = radius;
  cutter_orientation = orientation;
  cutter_first_move = true;
  comp_program_pos = pos;
  if (config.linuxcnc_comments) {
    canon.comment(cutter_side == 410 ? "interpreter: cutter radius compensation on left"
                                     : "interpreter: cutter radius compensation on right");
  }
}

void Interpreter::State::convert_tool_length_offset(int g) {
  if (cutter_side != 400) fail("Cannot change tool offset with cutter radius compensation on");
  Pose off{};
  if (g == 490) {
    // all zero
  } else if (g == 430 || (g == 432 && block.has_word('h'))) {
    int index = 0;
    if (block.has_word('h')) {
      const int h = static_cast<int>(block.get('h'));
      if (h != 0 || tools.is_random()) {
        const auto i = tools.find_tool_anywhere(h);
        if (!i) {
          char buf[80];
          std::snprintf(buf, sizeof buf, "Requested tool %d not found in the tool table", h);
          fail(buf);
        }
        index = *i;
      }
    } else {
      index = 0;  // the spindle
    }
    const ToolData& t = tools.at(index);
    for (int i = 0; i < kNumAxes; ++i) off[i] = to_program_axis(i, t.offset[i]);
    if (g == 432) {
      for (int i = 0; i < kNumAxes; ++i) off[i] += tool_offset[i];
    }
  } else {  // 431, or 432 with axis words
    if (g == 432 && !block.any_axis(config.axis_mask)) fail("G43.2: No axes specified and H word missing");
    // G43.1 replaces the offsets of the axes given and keeps the others;
    // G43.2 adds to them.
    static constexpr char letters[] = "xyzabcuvw";
    for (int i = 0; i < kNumAxes; ++i) {
      const char c = letters[i];
      if (g == 431) {
        off[i] = block.has_word(c) ? block.get(c) : tool_offset[i];
      } else {
        off[i] = tool_offset[i] + (block.has_word(c) ? block.get(c) : 0.0);
      }
    }
    if (g == 431 && diameter_mode && block.has_word('x')) off[0] /= 2.0;
  }
  // The machine stays; the program position shifts by the change (X and Y
  // turned into the rotated system, as LinuxCNC).
  double dx = tool_offset[0] - off[0], dy = tool_offset[1] - off[1];
  rotate_xy(dx, dy, -rotation);
  pos[0] += dx;
  pos[1] += dy;
  for (int i = 2; i < kNumAxes; ++i) pos[i] += tool_offset[i] - off[i];
  tool_offset = off;
  tool_offset_g = g;
  canon.use_tool_length_offset(off);
}

// Makes coordinate system `system` (1-9) the one in force, its origin and
// rotation taken from the parameters; the current point is expressed in it
// by `moved` (LinuxCNC's find_current_in_system, or M2's reset).
void Interpreter::State::load_origin(int system, const Pose& moved) {
  pos = moved;
  origin = system;
  params[5220] = system;
  const int base = 5201 + 20 * system;
  for (int i = 0; i < kNumAxes; ++i) origin_offset[i] = to_program_axis(i, params[static_cast<std::size_t>(base + i)]);
  rotation = params[static_cast<std::size_t>(base + 9)];
}

void Interpreter::State::convert_coordinate_system(int g) {
  if (cutter_side != 400) fail("Cannot change coordinate systems with cutter radius compensation on");
  int n = 1;
  switch (g) {
    case 540: n = 1; break;
    case 550: n = 2; break;
    case 560: n = 3; break;
    case 570: n = 4; break;
    case 580: n = 5; break;
    case 590: n = 6; break;
    case 591: n = 7; break;
    case 592: n = 8; break;
    case 593: n = 9; break;
    default: break;
  }
  if (n == origin) {
    if (config.linuxcnc_comments) canon.comment("interpreter: continuing to use same coordinate system");
    return;
  }
  load_origin(n, current_in_system(n, false));
  canon.set_g5x_offset(origin, origin_offset);
  canon.set_g92_offset(axis_offset);
  canon.set_xy_rotation(rotation);
}

void Interpreter::State::convert_control_mode(int g) {
  if (cutter_side != 400 && false) fail("Cannot change control mode with cutter radius compensation on");
  if (g == 610) {
    control = MotionMode::ExactPath;
    canon.set_motion_control_mode(MotionMode::ExactPath, 0);
  } else if (g == 611) {
    control = MotionMode::ExactStop;
    canon.set_motion_control_mode(MotionMode::ExactStop, 0);
  } else {
    control = MotionMode::Continuous;
    tolerance = block.has_word('p') ? block.get('p') : 0.0;
    naive_tolerance = block.has_word('q') ? block.get('q') : tolerance;
    canon.set_motion_control_mode(MotionMode::Continuous, tolerance);
    canon.set_naivecam_tolerance(naive_tolerance);
  }
}

void Interpreter::State::convert_axis_offsets(int g) {
  if (cutter_side != 400) fail("Cannot change axis offsets with cutter radius comp");
  static constexpr char letters[] = "xyzabcuvw";
  if (g == 920 || g == 520) {
    if (!block.any_axis(config.axis_mask)) fail("All axes missing with g52 or g92");
    for (int i = 0; i < kNumAxes; ++i) {
      const char c = letters[i];
      if (!block.has_word(c)) continue;
      double v = block.get(c);
      if (i == 0 && diameter_mode) v /= 2.0;
      if (g == 920) {
        const double next = pos[i] + axis_offset[i] - v;
        pos[i] = v;
        axis_offset[i] = next;
      } else {
        pos[i] = pos[i] + axis_offset[i] - v;
        axis_offset[i] = v;
      }
      params[static_cast<std::size_t>(5211 + i)] = to_machine_axis(i, axis_offset[i]);
    }
    params[5210] = 1.0;
  } else if (g == 921 || g == 922) {
    for (int i = 0; i < kNumAxes; ++i) {
      pos[i] += axis_offset[i];
      axis_offset[i] = 0;
      if (g == 921) params[static_cast<std::size_t>(5211 + i)] = 0;
    }
    params[5210] = 0;
  } else {  // 92.3
    for (int i = 0; i < kNumAxes; ++i) {
      const double next = to_program_axis(i, params[static_cast<std::size_t>(5211 + i)]);
      pos[i] = pos[i] + axis_offset[i] - next;
      axis_offset[i] = next;
    }
    params[5210] = 1.0;
  }
  canon.set_g92_offset(axis_offset);
}

void Interpreter::State::convert_coord_setup(int l) {
  // G10 L2 / L20 P(1-9, or 0 for the system in force) axis words, R
  // rotation (L2 only), as LinuxCNC's convert_setup.
  if (!block.has_word('p')) fail("P word missing with G10 L2");
  if (block.has_word('i') || block.has_word('j')) fail("I J words not allowed with G10 L2");
  int p = static_cast<int>(block.get('p') + 0.0001);
  if (p == 0) p = origin;
  if (p < 1 || p > 9) fail("P value out of range with G10 L2");
  if (cutter_side != 400 && p == origin) fail("Cannot change the active coordinate system with cutter radius compensation on");
  const int base = 5201 + 20 * p;
  const Pose current = current_in_system(p, false);
  double r = params[static_cast<std::size_t>(base + 9)];
  if (block.has_word('r')) {
    if (l == 20) fail("R not allowed in G10 L20");
    r = block.get('r');
    params[static_cast<std::size_t>(base + 9)] = r;
  }
  auto param = [&](int i) -> double& { return params[static_cast<std::size_t>(base + i)]; };
  auto word = [&](int i, double& v) {
    if (!block.has_word(kLetters[i])) return false;
    v = block.get(kLetters[i]);
    if (i == 0 && diameter_mode) v /= 2.0;
    return true;
  };
  Pose next{};
  double v = 0;
  if (l == 20) {
    // The origin that makes the current point read the values given, in
    // the system's rotated frame (both X and Y move under a rotation).
    double oldx = current[0], oldy = current[1];
    double x = word(0, v) ? v : current[0];
    double y = word(1, v) ? v : current[1];
    rotate_xy(oldx, oldy, r);
    rotate_xy(x, y, r);
    next[0] = oldx + to_program_axis(0, param(0)) - x;
    next[1] = oldy + to_program_axis(1, param(1)) - y;
    param(0) = to_machine_axis(0, next[0]);
    param(1) = to_machine_axis(1, next[1]);
  } else {
    for (int i = 0; i < 2; ++i) {
      if (word(i, v)) {
        next[i] = v;
        param(i) = to_machine_axis(i, v);
      } else {
        next[i] = to_program_axis(i, param(i));
      }
    }
  }
  for (int i = 2; i < kNumAxes; ++i) {
    if (word(i, v)) {
      if (l == 20) v = current[i] + to_program_axis(i, param(i)) - v;
      next[i] = v;
      param(i) = to_machine_axis(i, v);
    } else {
      next[i] = to_program_axis(i, param(i));
    }
  }
  if (p != origin) {
    if (config.linuxcnc_comments) canon.comment("interpreter: setting coordinate system origin");
    return;
  }
  // The system in force: the current point follows the new origin and
  // rotation.
  rotate_xy(pos[0], pos[1], rotation);
  for (int i = 0; i < kNumAxes; ++i) pos[i] += origin_offset[i] - next[i];
  origin_offset = next;
  canon.set_g5x_offset(origin, origin_offset);
  rotate_xy(pos[0], pos[1], -r);
  rotation = r;
  canon.set_xy_rotation(rotation);
}

void Interpreter::State::convert_setup_tool(int l) {
  // G10 L1 / L10 / L11 P<tool>: write the tool table (manual 3.24.3.4).
  if (!block.has_word('p')) fail("P word missing with G10 L1/L10/L11");
  const int toolno = static_cast<int>(round_to_int(block.get('p')));
  std::optional<int> index = tools.find_tool_anywhere(toolno);
  if (!tools.is_random() && index && *index == 0) index = tools.find_tool(toolno);
  if (!index) {
    char buf[80];
    std::snprintf(buf, sizeof buf, "Requested tool %d not found in the tool table", toolno);
    fail(buf);
  }
  ToolData t = tools.at(*index);
  bool any = block.has_word('r') || block.has_word('q') || block.has_word('i') || block.has_word('j');
  for (int i = 0; i < kNumAxes; ++i) any = any || block.has_word(kLetters[i]);
  if (!any) fail("G10 L1 without offsets has no effect");
  auto word = [&](int i, double& v) {
    if (!block.has_word(kLetters[i])) return false;
    v = block.get(kLetters[i]);
    if (i == 0 && diameter_mode) v /= 2.0;
    return true;
  };
  double v = 0;
  if (l == 1) {
    for (int i = 0; i < kNumAxes; ++i) {
      if (word(i, v)) t.offset[i] = to_machine_axis(i, v);
    }
  } else {
    // L10: the offset that makes the current point read the values given in
    // the system in force; L11: in G59.3 (and without its G92 offset). As
    // LinuxCNC, X and Y are measured in the system's rotated frame; with
    // only one of them given the other component of the offset is kept.
    const int system = l == 11 ? 9 : origin;
    Pose cur = current_in_system(system, true);
    if (l == 11 && params[5210] != 0.0) {
      for (int i = 0; i < kNumAxes; ++i) cur[i] += to_program_axis(i, params[static_cast<std::size_t>(5211 + i)]);
    }
    const double rot = params[static_cast<std::size_t>(5201 + 20 * system + 9)];
    double wx = 0, wy = 0;
    const bool has_x = word(0, wx), has_y = word(1, wy);
    if (has_x || has_y) {
      double tx = cur[0], ty = cur[1];
      double ox = 0, oy = 0;  // the kept component of the old offset
      if (has_x && has_y) {
        tx -= wx;
        ty -= wy;
      } else {
        ox = to_program_axis(0, t.offset[0]);
        oy = to_program_axis(1, t.offset[1]);
        rotate_xy(ox, oy, -rot);
        if (has_x) {
          ox = 0;
          tx -= wx;
          ty = 0;
        } else {
          oy = 0;
          ty -= wy;
          tx = 0;
        }
        rotate_xy(ox, oy, rot);
      }
      rotate_xy(tx, ty, rot);
      t.offset[0] = to_machine_axis(0, tx + ox);
      t.offset[1] = to_machine_axis(1, ty + oy);
    }
    for (int i = 2; i < kNumAxes; ++i) {
      if (word(i, v)) t.offset[i] = to_machine_axis(i, cur[i] - v);
    }
  }
  if (block.has_word('r')) t.diameter = to_machine_len(block.get('r') * 2.0);
  if (block.has_word('i')) t.front_angle = block.get('i');
  if (block.has_word('j')) t.back_angle = block.get('j');
  if (block.has_word('q')) {
    const int q = static_cast<int>(round_to_int(block.get('q')));
    if (q < 0 || q > 9) fail("Invalid tool orientation");
    t.orientation = q;
  }
  const int written = tools.update_tool(t);
  canon.set_tool_table_entry(written, t);
  // Non-random changers: the entry the spindle's tool came from (as the
  // machine reports it, Canon::tool_slot()) is copied to the spindle entry,
  // and the canon learns it with a second entry, as LinuxCNC does.
  if (!tools.is_random() && written == current_index && written != 0) {
    tools.set_slot(0, tools.at(written));
    canon.set_tool_table_entry(0, tools.at(written));
  }
}

void Interpreter::State::convert_g() {
  if (block.g[kGNonModal] == 40) convert_dwell();
  if (block.g[kGPlane] != -1) convert_plane(block.g[kGPlane]);
  if (block.g[kGUnits] != -1) convert_units(block.g[kGUnits] == 200 ? Units::Inch : Units::Mm);
  if (block.g[kGLathe] != -1 && (block.g[kGLathe] == 70) != diameter_mode) {
    diameter_mode = block.g[kGLathe] == 70;
    if (config.linuxcnc_comments) {
      canon.comment(diameter_mode ? "interpreter: Lathe diameter mode changed to diameter"
                                  : "interpreter: Lathe diameter mode changed to radius");
    }
  }
  if (block.g[kGCutter] != -1) convert_cutter_comp(block.g[kGCutter]);
  if (block.g[kGToolOffset] != -1) convert_tool_length_offset(block.g[kGToolOffset]);
  if (block.g[kGCoordSys] != -1) convert_coordinate_system(block.g[kGCoordSys]);
  if (block.g[kGControl] != -1) convert_control_mode(block.g[kGControl]);
  if (block.g[kGDistance] != -1) set_distance_mode(block.g[kGDistance] == 900);
  if (block.g[kGIjk] != -1) {
    const bool abs_ijk = block.g[kGIjk] == 901;
    if (abs_ijk != ijk_absolute && config.linuxcnc_comments) {
      canon.comment(abs_ijk ? "interpreter: IJK distance mode changed to absolute"
                            : "interpreter: IJK distance mode changed to incremental");
    }
    ijk_absolute = abs_ijk;
  }
  if (block.g[kGRetract] != -1) {
    if (cutter_side != 400) fail("Cannot change retract mode with cutter radius compensation on");
    retract_old_z = block.g[kGRetract] == 980;
    if (config.linuxcnc_comments) {
      canon.comment(retract_old_z ? "interpreter: retract mode set to old_z" : "interpreter: retract mode set to r_plane");
    }
  }
  const int g0 = block.g[kGNonModal];
  switch (g0) {
    case 100: {
      const int l = block.has_word('l') ? static_cast<int>(block.get('l')) : -1;
      if (l == 2 || l == 20) {
        convert_coord_setup(l);
      } else if (l == 1 || l == 10 || l == 11) {
        convert_setup_tool(l);
      } else {
        fail("Line with G10 does not have L0, L1, L10, L11, L2, or L20");
      }
      break;
    }
    case 280:
    case 300:
      convert_home(g0);
      break;
    case 281:
    case 301: {
      if (cutter_side != 400) fail("Cannot set reference point with cutter compensation in effect");
      const int base = g0 == 281 ? 5161 : 5181;
      const Pose machine = program_to_machine(pos);
      for (int i = 0; i < kNumAxes; ++i) params[static_cast<std::size_t>(base + i)] = to_machine_axis(i, machine[i]);
      break;
    }
    case 520:
    case 920:
    case 921:
    case 922:
    case 923:
      convert_axis_offsets(g0);
      break;
    default:
      break;
  }
}

// The motion step: G code of group 1, or axis words in the modal motion.
void Interpreter::State::convert_g_motion(Status& st) {
  const int g0 = block.g[kGNonModal];
  int motion = block.g[kGMotion];
  if (motion == 800 && block.any_axis(config.axis_mask) && g0 != 100 && g0 != 280 && g0 != 300 && g0 != 520 &&
      g0 != 920 && block.g[kGToolOffset] != 431 && block.g[kGToolOffset] != 432) {
    fail("Cannot use axis values with g80");
  }
  const bool has_axes = block.any_axis(config.axis_mask) || block.has_polar_r || block.has_polar_a;
  if (motion == -1 && g0 != 100 && g0 != 280 && g0 != 300 && g0 != 520 && g0 != 920 && g0 != 431 &&
      block.g[kGToolOffset] != 431 && block.g[kGToolOffset] != 432 && has_axes) {
    motion = motion_mode;
    if (motion < 0) fail("Cannot use axis values without a g code that uses them");
  }
  if (motion != -1) convert_motion(motion, st);
}

void Interpreter::State::convert_home(int g) {
  if (cutter_side != 400) fail("Cannot use g28 or g30 with cutter radius comp");
  const Pose mid = find_ends(false);
  emit_traverse(mid);
  const int base = g == 280 ? 5161 : 5181;
  const bool any = block.any_axis(config.axis_mask);
  static constexpr char letters[] = "xyzabcuvw";
  // The home position is stored in machine coordinates; in program
  // coordinates, only the axes named (all when none) go there.
  Pose machine{};
  for (int i = 0; i < kNumAxes; ++i) machine[i] = to_program_axis(i, params[static_cast<std::size_t>(base + i)]);
  const Pose target = machine_to_program(machine);
  Pose home = mid;
  for (int i = 0; i < kNumAxes; ++i) {
    if (any && !block.has_word(letters[i])) continue;
    home[i] = target[i];
  }
  emit_traverse(home);
}

void Interpreter::State::end_program(bool pallet) {
  // Back to G54 keeping the point on the machine (the G92 offset stays).
  Pose p = pos;
  rotate_xy(p[0], p[1], rotation);
  for (int i = 0; i < kNumAxes; ++i) p[i] += origin_offset[i] - to_program_axis(i, params[static_cast<std::size_t>(5221 + i)]);
  rotate_xy(p[0], p[1], -params[5230]);
  load_origin(1, p);
  canon.set_g5x_offset(1, origin_offset);
  canon.set_xy_rotation(rotation);
  if (plane != Plane::XY) {
    plane = Plane::XY;
    canon.select_plane(plane);
  }
  absolute = true;
  feed_mode = FeedMode::UnitsPerMinute;
  canon.set_feed_mode(0, FeedMode::UnitsPerMinute);
  feed = 0;
  canon.set_feed_rate(0);
  if (!feed_override) {
    canon.enable_feed_override();
    feed_override = true;
  }
  if (!speed_override) {
    canon.enable_speed_override(0);
    speed_override = true;
  }
  if (cutter_side != 400) {
    comp_flush();
    cutter_side = 400;
  }
  // every spindle stops and goes back to RPM mode, in order
  for (int k = 0; k < config.spindles; ++k) {
    set_direction(k, Direction::Stopped);
    if (k == 0) {
      css = false;
    } else {
      other_spindles[static_cast<std::size_t>(k)].css = false;
    }
    canon.set_spindle_mode(k, 0);
  }
  motion_mode = 10;
  if (mist) {
    canon.mist_off();
    mist = false;
  }
  if (flood) {
    canon.flood_off();
    flood = false;
  }
  // [RS274NGC]DISABLE_G92_PERSISTENCE: the G92/G52 offset is not kept
  // (the parameters are cleared; the offset in force stays until reset).
  if (config.disable_g92_persistence) {
    for (int k = 5210; k <= 5219; ++k) params[static_cast<std::size_t>(k)] = 0.0;
  }
  if (pallet) canon.pallet_shuttle();
  canon.program_end();
}

void Interpreter::State::convert_stop(Status& st) {
  const int m = block.m[kMStop];
  // Every stop sends the held-back move first (LinuxCNC 2.9: before M2's
  // offset and coolant resets too).
  if (cutter_side != 400) comp_flush();
  switch (m) {
    case 0: canon.program_stop(); break;
    case 1: canon.optional_program_stop(); break;
    case 60:
      canon.pallet_shuttle();
      canon.program_stop();
      break;
    case 2:
    case 30:
      end_program(m == 30);
      program_ended = true;
      st = Status::ProgramEnd;
      break;
    case 98: convert_fanuc_call(); break;
    case 99: convert_fanuc_return(st); break;
    default: break;
  }
}

// M98 P<n> [L<times>]: runs the Fanuc-style subprogram O<n> ... M99.
void Interpreter::State::convert_fanuc_call() {
  if (config.disable_fanuc_style_sub) fail("DISABLE_FANUC_STYLE_SUB set in INI file, but found m98");
  if (!block.has_word('p')) fail("Found 'm98' code with no P-word");
  const int times = block.has_word('l') ? round_to_int(block.get('l')) : 1;
  if (times <= 0) return;
  block.o_name = std::to_string(round_to_int(block.get('p')));
  block.call_args.clear();
  do_call(true, times);
}

// M99: back from an M98 subprogram (or into it again for L). In the main
// program it ends the program as M2 does, or, in the task controller
// (Config::task, as LinuxCNC's task), starts it again from the top.
void Interpreter::State::convert_fanuc_return(Status& st) {
  if (config.disable_fanuc_style_sub) fail("DISABLE_FANUC_STYLE_SUB set in INI file, but found m99");
  if (frames.size() > 1) {
    Frame& f = frame();
    if (!f.fanuc) fail("'O.... endsub' or 'O.... return' must follow 'O.... sub' subroutine definition");
    if (f.fanuc_repeats > 0) {
      --f.fanuc_repeats;
      jump(f.fanuc_def.offset, f.fanuc_def.line);
      return;
    }
    do_return(false, 0.0);
    return;
  }
  if (config.task && !files.empty() && files.back().path != "<mdi>") {
    jump(0, 0);
    first_line = true;
    return;
  }
  end_program(false);
  program_ended = true;
  st = Status::ProgramEnd;
}

}  // namespace cnc::interp
