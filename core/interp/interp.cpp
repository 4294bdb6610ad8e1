// The public Interpreter API over Interpreter::State.
#include "core/interp/interp.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "core/ini/ini_file.hpp"
#include "core/util/strings.hpp"
#include "core/interp/impl.hpp"

namespace cnc::interp {

InterpError::InterpError(std::string message, std::string file, int line, std::string block_text)
    : std::runtime_error(file.empty() ? message : file + ":" + std::to_string(line) + ": " + message),
      message_(std::move(message)), file_(std::move(file)), line_(line), block_text_(std::move(block_text)) {}

const char* to_string(Status s) noexcept {
  switch (s) {
    case Status::Ok: return "ok";
    case Status::ExecuteFinish: return "execute-finish";
    case Status::SynchRequired: return "synch-required";
    case Status::ProgramEnd: return "program-end";
    case Status::EndOfFile: return "end-of-file";
    case Status::Yield: return "yield";
  }
  return "?";
}

const char* to_string(Units u) noexcept {
  switch (u) {
    case Units::Inch: return "CANON_UNITS_INCHES";
    case Units::Mm: return "CANON_UNITS_MM";
    case Units::Cm: return "CANON_UNITS_CM";
  }
  return "?";
}

const char* to_string(Plane p) noexcept {
  switch (p) {
    case Plane::XY: return "CANON_PLANE_XY";
    case Plane::YZ: return "CANON_PLANE_YZ";
    case Plane::XZ: return "CANON_PLANE_XZ";
    case Plane::UV: return "CANON_PLANE_UV";
    case Plane::VW: return "CANON_PLANE_VW";
    case Plane::UW: return "CANON_PLANE_UW";
  }
  return "?";
}

std::string RemapSpec::name() const {
  if (letter == 'g') {
    char buf[24];
    if (code % 10 != 0) {
      std::snprintf(buf, sizeof buf, "G%d.%d", code / 10, code % 10);
    } else {
      std::snprintf(buf, sizeof buf, "G%d", code / 10);
    }
    return buf;
  }
  if (letter == 'm') return "M" + std::to_string(code);
  return std::string(1, static_cast<char>(letter - 32));
}

namespace {

// A subroutine name given to REMAP (ngc=, prolog=, epilog=) must be found as
// name.ngc in SUBROUTINE_PATH (or beside the INI file).
bool ngc_file_exists(const Config& c, const cnc::ini::IniFile& ini, const std::string& name) {
  std::vector<std::filesystem::path> dirs = c.subroutine_path;
  dirs.push_back(ini.directory());
  for (const auto& d : dirs) {
    std::error_code ec;
    if (std::filesystem::exists(d / (name + ".ngc"), ec) || std::filesystem::exists(d / (name + ".NGC"), ec)) return true;
  }
  return false;
}

// Parses one REMAP= value as LinuxCNC does: the code, then key=value words.
RemapSpec parse_remap(const Config& c, const cnc::ini::IniFile& ini, const cnc::ini::Entry& e) {
  RemapSpec r;
  r.where = e.file + ":" + std::to_string(e.line);
  std::vector<std::string> words;
  {
    std::istringstream in(e.value);
    for (std::string w; in >> w;) words.push_back(w);
  }
  auto bad = [&](const std::string& what) { ini.fail(&e, "REMAP=" + e.value + ": " + what); };
  if (words.empty()) bad("no code to remap");
  const std::string code = cnc::to_lower(words[0]);
  r.letter = code[0];
  const std::string number = code.substr(1);
  if (r.letter == 't' || r.letter == 's' || r.letter == 'f') {
    if (!number.empty()) bad("T, S and F are remapped without a number");
  } else if (r.letter == 'g' || r.letter == 'm') {
    char* end = nullptr;
    const double v = std::strtod(number.c_str(), &end);
    if (number.empty() || end == nullptr || *end != '\0' || !(v >= 0) || v > 999) bad("'" + words[0] + "' is not a G or M code");
    r.code = static_cast<int>(std::lround(v * (r.letter == 'g' ? 10 : 1)));
    if (std::fabs(v * (r.letter == 'g' ? 10 : 1) - r.code) > 1e-6) bad("'" + words[0] + "' is not a G or M code");
  } else {
    bad("only G and M codes, T, S and F can be remapped");
  }
  bool group_given = false;
  for (std::size_t k = 1; k < words.size(); ++k) {
    const std::size_t eq = words[k].find('=');
    if (eq == std::string::npos) bad("'" + words[k] + "' is not key=value");
    const std::string key = cnc::to_lower(words[k].substr(0, eq));
    const std::string value = words[k].substr(eq + 1);
    if (key == "modalgroup") {
      char* end = nullptr;
      const long g = std::strtol(value.c_str(), &end, 10);
      if (value.empty() || *end != '\0') bad("modalgroup=" + value + " is not a number");
      r.modal_group = static_cast<int>(g);
      group_given = true;
    } else if (key == "argspec") {
      for (char ch : value) {
        const char l = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
        if (ch == '@' || ch == '>' || ch == '^') continue;
        if (l < 'a' || l > 'z' || l == 'g' || l == 'm' || l == 'n' || l == 'o') {
          bad(std::string("argspec: '") + ch + "' is not a word letter, @, > or ^");
        }
      }
      r.argspec = value;
    } else if (key == "ngc") {
      r.ngc = cnc::to_lower(value);
    } else if (key == "prolog" || key == "epilog") {
      // LinuxCNC's prolog/epilog are Python functions (module `remap`);
      // here a subroutine file of that name is taken first.
      const bool python = !ngc_file_exists(c, ini, cnc::to_lower(value));
      if (python && !ini.has_section("PYTHON")) {
        bad(key + "=" + value + " names no subroutine file " + value +
            ".ngc in SUBROUTINE_PATH, and without [PYTHON] it cannot be a Python function");
      }
      (key == "prolog" ? r.prolog : r.epilog) = python ? value : cnc::to_lower(value);
      (key == "prolog" ? r.prolog_python : r.epilog_python) = python;
    } else if (key == "py" || key == "python") {
      if (!ini.has_section("PYTHON")) bad(key + "=" + value + ": a Python remap procedure needs [PYTHON] (TOPLEVEL)");
      r.python = value;
    } else {
      bad("unknown key '" + key + "' (modalgroup, argspec, ngc, py, prolog, epilog)");
    }
  }
  if (r.ngc.empty() && r.python.empty()) {
    bad("ngc= or py= is missing (the O-word subroutine or Python function that implements " + r.name() + ")");
  }
  if (!r.ngc.empty() && !r.python.empty()) bad("ngc= and py= both given: one body only");
  if (!r.python.empty() && ((!r.prolog.empty() && !r.prolog_python) || (!r.epilog.empty() && !r.epilog_python))) {
    bad("a subroutine prolog or epilog needs an ngc= body (py= takes Python ones)");
  }
  if (r.letter == 'g') {
    if (!group_given) r.modal_group = 1;
    if (r.modal_group != 1) bad("a G code can only be remapped in modal group 1");
    if (builtin_g_group(r.code) >= 0) bad(r.name() + " is a built-in G code, which cannot be remapped");
  } else if (r.letter == 'm') {
    const int builtin = builtin_m_group(r.code);
    if (r.code == 0 || r.code == 1 || r.code == 60) {
      r.modal_group = 4;
    } else if (r.code == 6 || r.code == 61) {
      r.modal_group = 6;
    } else if (builtin >= 0 && !(r.code >= 100 && r.code <= 199)) {
      bad(r.name() + " is a built-in M code that cannot be remapped (M0, M1, M60, M6 and M61 can)");
    } else if (!group_given) {
      r.modal_group = 10;
    } else if (r.modal_group < 5 || r.modal_group > 10) {
      bad("modalgroup=" + std::to_string(r.modal_group) + ": an M code is remapped in modal group 5 to 10");
    }
  }
  for (const RemapSpec& o : c.remaps) {
    if (o.letter == r.letter && o.code == r.code) bad(r.name() + " is already remapped at " + o.where);
  }
  return r;
}

}  // namespace

Config Config::from_ini(const cnc::ini::IniFile& ini) {
  Config c;
  c.ini = &ini;
  if (const auto v = ini.find("RS274NGC", "PARAMETER_FILE")) c.parameter_file = ini.resolve_path(*v);
  if (const auto v = ini.find("RS274NGC", "SUBROUTINE_PATH")) {
    for (const auto& part : cnc::split(*v, ':', true)) c.subroutine_path.push_back(ini.resolve_path(part));
  }
  if (const auto v = ini.find("RS274NGC", "USER_M_PATH")) {
    for (const auto& part : cnc::split(*v, ':', true)) c.user_m_path.push_back(ini.resolve_path(part));
  }
  c.startup_code = ini.get_string("RS274NGC", "RS274NGC_STARTUP_CODE", "");
  c.random_toolchanger = ini.get_bool("EMCIO", "RANDOM_TOOLCHANGER", false);
  c.tool_change_with_spindle_on = ini.get_bool("EMCIO", "TOOL_CHANGE_WITH_SPINDLE_ON", false);
  c.disable_g92_persistence = ini.get_bool("RS274NGC", "DISABLE_G92_PERSISTENCE", false);
  c.orient_offset = ini.get_double("RS274NGC", "ORIENT_OFFSET", 0.0, {0, 360});
  c.center_arc_radius_tolerance_inch =
      ini.get_double("RS274NGC", "CENTER_ARC_RADIUS_TOLERANCE_INCH", c.center_arc_radius_tolerance_inch,
                     {kMinCenterArcToleranceInch, kDefaultCenterArcToleranceInch});
  c.center_arc_radius_tolerance_mm =
      ini.get_double("RS274NGC", "CENTER_ARC_RADIUS_TOLERANCE_MM", c.center_arc_radius_tolerance_mm,
                     {kMinCenterArcToleranceMm, kDefaultCenterArcToleranceMm});
  c.max_blocks_without_output =
      ini.get_int("RS274NGC", "MAX_BLOCKS_WITHOUT_OUTPUT", c.max_blocks_without_output, {10, 1e12});
  c.oword_nargs = ini.get_bool("RS274NGC", "OWORD_NARGS", false);
  c.disable_fanuc_style_sub = ini.get_bool("RS274NGC", "DISABLE_FANUC_STYLE_SUB", false);
  for (const cnc::ini::Entry* e : ini.find_all_entries("RS274NGC", "REMAP")) c.remaps.push_back(parse_remap(c, ini, *e));
  // cncd's task takes the number from motion, the owner of [TRAJ]SPINDLES;
  // stand-alone tools (cnc-rs274, the screen's preview) read it here
  c.spindles = std::max(1, static_cast<int>(ini.get_int("TRAJ", "SPINDLES", 1, {0, Config::kMaxSpindles})));
  if (const auto v = ini.find("TRAJ", "COORDINATES")) {
    unsigned mask = 0;
    for (char ch : *v) {
      const int a = axis_index(ch);
      if (a >= 0) mask |= 1u << a;
    }
    if (mask != 0) c.axis_mask = mask;
  }
  if (const auto v = ini.find("TRAJ", "LINEAR_UNITS")) {
    const std::string u = cnc::to_lower(*v);
    if (u == "inch" || u == "in" || u == "imperial") c.default_units = Units::Inch;
  }
  return c;
}

Interpreter::State::State(Canon& c, Config cfg) : queueing(c), canon(queueing), config(std::move(cfg)) {
  tools = cnc::tooltable::ToolTable(config.random_toolchanger ? cnc::tooltable::ChangerKind::Random
                                                              : cnc::tooltable::ChangerKind::NonRandom);
  init_parameters();
  frames.emplace_back();
}

Interpreter::Interpreter(Canon& canon, Config config) : s_(std::make_unique<State>(canon, std::move(config))) {}

Interpreter::~Interpreter() = default;

void Interpreter::init() {
  State& s = *s_;
  s.files.clear();
  s.subs.clear();
  s.init_parameters();
  s.load_parameter_file();
  s.params[5599] = 1.0;  // (DEBUG,...) output on, as LinuxCNC starts
  if (s.config.disable_g92_persistence) {
    for (int k = 5210; k <= 5219; ++k) s.params[static_cast<std::size_t>(k)] = 0.0;
  }
  s.reset_modal(true);
  s.update_tool_from_canon();
  s.canon_init_calls();
  if (s.config.script) {
    s.config.script->attach(*this, s.canon);
    // Every Python function a REMAP names must exist
    for (const RemapSpec& r : s.config.remaps) {
      for (const auto& [name, python] : {std::pair{r.python, !r.python.empty()}, std::pair{r.prolog, r.prolog_python},
                                         std::pair{r.epilog, r.epilog_python}}) {
        if (python && !s.config.script->has_remap(name)) {
          const std::size_t colon = r.where.rfind(':');
          throw InterpError("REMAP " + r.name() + ": " + name + " is no function of the Python module `remap`",
                            r.where.substr(0, colon), colon == std::string::npos ? 0 : std::atoi(r.where.c_str() + colon + 1),
                            {});
        }
      }
    }
  }
  if (!s.config.startup_code.empty()) {
    execute(s.config.startup_code);
  }
}

void Interpreter::reset() {
  State& s = *s_;
  s.machine_waited();
  s.files.clear();
  s.subs.clear();
  s.program_path.clear();
  s.frames.clear();
  s.frames.emplace_back();
  s.exec_step = 0;
  s.resume_block = false;
  s.drop_stages();
  s.reset_modal(true);
  s.update_tool_from_canon();
  s.canon.on_reset();
}

void Interpreter::open(const std::filesystem::path& program) {
  State& s = *s_;
  s.files.clear();
  s.frames.clear();
  s.frames.emplace_back();
  s.subs.clear();
  s.o_label_lines.clear();
  s.percent_seen = false;
  s.first_line = true;
  s.program_ended = false;
  s.skipping = false;
  s.exec_step = 0;
  s.resume_block = false;
  s.drop_stages();
  s.current_line = 0;
  s.current_file = program.string();
  s.line_text.clear();
  s.program_path = program.string();
  s.program_display_name = program.string();
  s.machine_waited();
  s.open_file(program.string());
  // As LinuxCNC: leading blank lines are skipped looking for a '%' line; a
  // file with nothing else cannot be opened.
  LineReader& r = *s.files.back().reader;
  std::string_view raw;
  for (;;) {
    const int64_t offset = r.offset();
    const int line_before = r.line_number();
    if (!r.next(raw)) {
      s.files.clear();
      throw InterpError("File ended with no percent sign", program.string(), line_before, "");
    }
    if (cnc::trim(raw).empty()) continue;
    s.first_line = false;
    if (cnc::trim(raw).front() == '%') {
      s.percent_seen = true;
    } else {
      r.seek(offset, line_before);
    }
    break;
  }
}

void Interpreter::open_at_line(const std::filesystem::path& program, int line) {
  open(program);
  State& s = *s_;
  // Learn subroutine definitions on the way; execute nothing.
  std::string_view raw;
  LineReader& r = *s.files.back().reader;
  while (r.line_number() + 1 < line) {
    const int64_t off = r.offset();
    if (!r.next(raw)) break;
    s.current_line = r.line_number();
    s.line_text.assign(raw);
    if (s.first_line) {
      s.first_line = false;
      std::string_view t = cnc::trim(raw);
      if (!t.empty() && t[0] == '%') {
        s.percent_seen = true;
        continue;
      }
    }
    std::size_t i = 0;
    while (i < raw.size() && (raw[i] == ' ' || raw[i] == '\t')) ++i;
    if (i >= raw.size() || (raw[i] != 'o' && raw[i] != 'O')) continue;
    s.parse_line(raw);
    if (s.block.o_type == OType::Sub) {
      s.subs[s.block.o_name] = SubDef{s.files.back().path, r.offset(), r.line_number()};
    }
    (void)off;
  }
}

void Interpreter::close() {
  s_->files.clear();
  s_->program_path.clear();
}

bool Interpreter::is_open() const noexcept { return !s_->files.empty(); }

Status Interpreter::read() {
  State& s = *s_;
  if (s.synch_pending) return Status::SynchRequired;
  if (s.stage.kind != State::StageKind::None) {
    // A remap's Python stage waits to be resumed: execute() does, nothing is read.
    s.block_ready = true;
    return Status::Ok;
  }
  if (s.files.empty()) {
    if (s.program_ended) return Status::ProgramEnd;
    throw InterpError("File not open", "", 0, "");
  }
  s.block_ready = false;
  s.lines_this_read = 0;
  switch (s.read_block()) {
    case ReadResult::Block: s.block_ready = true; return Status::Ok;
    case ReadResult::Yield: return Status::Yield;
    case ReadResult::End: break;
  }
  return s.program_ended ? Status::ProgramEnd : Status::EndOfFile;
}

Status Interpreter::read(std::string_view mdi_line) {
  State& s = *s_;
  if (s.synch_pending) return Status::SynchRequired;
  if (s.stage.kind != State::StageKind::None) {
    throw InterpError("a remap procedure (" + s.stage.rc->spec->name() +
                          ") waits to be resumed: read() goes on with it, a new MDI line cannot start",
                      s.current_file, s.current_line, s.line_text);
  }
  SourceFile f;
  f.reader = std::make_unique<LineReader>(LineReader::from_string(std::string(mdi_line)));
  f.path = "<mdi>";
  s.push_source(std::move(f));
  s.first_line = false;
  s.machine_waited();  // a new command: its own count of lines without output
  s.block_ready = false;
  s.lines_this_read = 0;
  switch (s.read_block()) {
    case ReadResult::Block: s.block_ready = true; return Status::Ok;
    case ReadResult::Yield: return Status::Yield;
    case ReadResult::End: break;
  }
  return Status::EndOfFile;
}

Status Interpreter::execute() {
  State& s = *s_;
  if (!s.block_ready) return Status::Ok;
  s.block_ready = false;
  const Status st = s.execute_ready();
  if (st == Status::ExecuteFinish) s.synch_pending = true;
  if (st == Status::ProgramEnd) {
    s.drop_stages();
    s.files.clear();
    s.frames.clear();
    s.frames.emplace_back();
  }
  return st;
}

Status Interpreter::execute(std::string_view mdi_line) {
  State& s = *s_;
  const std::size_t depth = s.files.size();
  Status st = read(mdi_line);
  Status last = Status::Ok;
  for (;;) {
    if (st == Status::Yield) {
      st = read();
      continue;
    }
    if (st != Status::Ok) break;
    last = execute();
    if (last == Status::ExecuteFinish) synch();
    if (last == Status::ProgramEnd) return last;
    if (s.files.size() <= depth) break;
    st = read();
  }
  while (s.files.size() > depth) s.pop_source();
  return last == Status::ExecuteFinish ? Status::Ok : last;
}

void Interpreter::synch() {
  State& s = *s_;
  s.pos = s.canon.current_position();
  s.update_tool_from_canon();
  if (s.probe_pending) {
    s.probe_pending = false;
    s.probe_pos = s.canon.probe_position();
    s.probe_ok = s.canon.probe_tripped();
    for (int i = 0; i < kNumAxes; ++i) s.params[static_cast<std::size_t>(5061 + i)] = s.probe_pos[i];
    s.params[5070] = s.probe_ok ? 1.0 : 0.0;
  }
  s.params[5399] = s.canon.input_value();
  s.synch_pending = false;
  s.machine_waited();
}

void Interpreter::unwind() {
  State& s = *s_;
  while (s.frames.size() > 1) {
    Frame f = std::move(s.frames.back());
    s.frames.pop_back();
    for (int k = 0; k < 30; ++k) s.params[static_cast<std::size_t>(k + 1)] = f.saved_args[static_cast<std::size_t>(k)];
    while (static_cast<int>(s.files.size()) > f.file_depth) s.pop_source();
    if (!s.files.empty()) s.jump(f.return_offset, f.return_line);
  }
  s.skipping = false;
  s.skip_defining = false;
  s.block_ready = false;
  s.exec_step = 0;
  s.resume_block = false;
  s.drop_stages();
  s.queueing.queue().clear();
  s.comp_start_valid = false;
}

std::vector<std::string> Interpreter::call_stack() const {
  const State& s = *s_;
  std::vector<std::string> out;
  for (std::size_t k = 1; k < s.frames.size(); ++k) {
    const Frame& f = s.frames[k];
    const std::size_t depth = static_cast<std::size_t>(f.file_depth);
    const std::string file = depth >= 1 && depth <= s.files.size() ? s.files[depth - 1].path : std::string("?");
    out.push_back("o<" + f.sub_name + "> called at " + file + ":" + std::to_string(f.return_line));
  }
  return out;
}

bool Interpreter::is_synch_pending() const noexcept { return s_->synch_pending; }

Status Interpreter::run_to_end() {
  for (;;) {
    Status st = read();
    if (st == Status::SynchRequired) {
      synch();
      continue;
    }
    if (st == Status::Yield) continue;
    if (st != Status::Ok) return st;
    st = execute();
    if (st == Status::ExecuteFinish) synch();
    if (st == Status::ProgramEnd) return st;
  }
}

void Interpreter::save_parameters() const { s_->save_parameter_file(); }

int Interpreter::line() const noexcept { return s_->current_line; }
int Interpreter::n_number() const noexcept { return s_->n_number; }
const std::string& Interpreter::file_name() const noexcept { return s_->current_file; }
int Interpreter::call_level() const noexcept { return static_cast<int>(s_->frames.size()) - 1; }

int Interpreter::remap_level() const noexcept { return s_->remap_level(); }

double Interpreter::spindle_speed(int k) const noexcept {
  if (k <= 0) return s_->speed;
  return k < Config::kMaxSpindles ? s_->other_spindles[static_cast<std::size_t>(k)].speed : 0.0;
}

double Interpreter::parameter(int index) const {
  if (index < 1 || index >= kMaxParameters) return 0.0;
  return s_->get_param(index);
}

void Interpreter::set_parameter(int index, double value) {
  if (index < 1 || index >= kMaxParameters) return;
  s_->params[static_cast<std::size_t>(index)] = value;
}

bool Interpreter::named_parameter(std::string_view name, double& value) const {
  return s_->find_named(cnc::to_lower(name), value);
}

void Interpreter::set_named_parameter(std::string_view name, double value) {
  s_->set_named(cnc::to_lower(name), value);
}

const cnc::tooltable::ToolTable& Interpreter::tool_table() const noexcept { return s_->tools; }

Pose Interpreter::tool_offset() const noexcept { return s_->tool_offset; }

Canon& Interpreter::canon() noexcept { return s_->canon; }

std::vector<int> Interpreter::active_g_codes() const {
  const State& s = *s_;
  std::vector<int> g;
  g.push_back(s.motion_mode < 0 ? 800 : s.motion_mode);  // G80 or none
  static constexpr int planes[] = {170, 190, 180, 171, 191, 181};
  g.push_back(planes[static_cast<int>(s.plane)]);
  g.push_back(s.absolute ? 900 : 910);
  g.push_back(s.ijk_absolute ? 901 : 911);
  g.push_back(s.feed_mode == FeedMode::InverseTime ? 930 : s.feed_mode == FeedMode::UnitsPerRev ? 950 : 940);
  g.push_back(s.units == Units::Inch ? 200 : 210);
  g.push_back(s.cutter_side);
  g.push_back(s.tool_offset_g);
  g.push_back(s.retract_old_z ? 980 : 990);
  static constexpr int coords[] = {540, 550, 560, 570, 580, 590, 591, 592, 593};
  g.push_back(coords[s.origin - 1]);
  g.push_back(s.control == MotionMode::ExactPath ? 610 : s.control == MotionMode::ExactStop ? 611 : 640);
  g.push_back(s.css ? 960 : 970);
  g.push_back(s.diameter_mode ? 70 : 80);
  return g;
}

std::vector<Interpreter::NamedParameter> Interpreter::named_parameters(int level) const {
  const State& s = *s_;
  std::vector<NamedParameter> out;
  if (level < 0 || level >= static_cast<int>(s.frames.size())) return out;
  if (level == 0) {
    // LinuxCNC 2.9's predefined parameters (its init_named_parameters)
    static constexpr const char* kPredefined[] = {
        "_vmajor", "_vminor", "_metric_machine", "_line", "_motion_mode", "_plane", "_ccomp", "_metric", "_imperial",
        "_absolute", "_incremental", "_inverse_time", "_units_per_minute", "_units_per_rev", "_coord_system",
        "_tool_offset", "_retract_r_plane", "_retract_old_z", "_spindle_rpm_mode", "_spindle_css_mode",
        "_ijk_absolute_mode", "_lathe_diameter_mode", "_lathe_radius_mode", "_spindle_on", "_spindle_cw", "_mist",
        "_flood", "_speed_override", "_feed_override", "_adaptive_feed", "_feed_hold", "_feed", "_rpm",
        "_current_tool", "_current_pocket", "_selected_pocket", "_selected_tool", "_x", "_y", "_z", "_a", "_b", "_c",
        "_u", "_v", "_w", "_abs_x", "_abs_y", "_abs_z", "_abs_a", "_abs_b", "_abs_c", "_value", "_value_returned",
        "_task", "_call_level", "_remap_level"};
    for (const char* name : kPredefined) {
      double v = 0;
      if (s.predefined(name, v)) out.push_back({name, v, 1 | 2});
    }
    for (const std::string& name : s.ini_names_read) {
      double v = 0;
      if (s.predefined(name, v)) out.push_back({name, v, 1 | 2 | 16});
    }
    if (s.config.script) {
      for (const std::string& name : s.config.script->script_parameters()) out.push_back({name, 0.0, 1 | 2 | 32});
    }
    for (const auto& [name, v] : s.globals) out.push_back({name, v, 2});
  }
  for (const auto& [name, v] : s.frames[static_cast<std::size_t>(level)].locals) out.push_back({name, v, 0});
  std::sort(out.begin(), out.end(), [](const NamedParameter& a, const NamedParameter& b) { return a.name < b.name; });
  // a global assigned over a predefined name (_value) is listed once
  out.erase(std::unique(out.begin(), out.end(), [](const NamedParameter& a, const NamedParameter& b) { return a.name == b.name; }),
            out.end());
  return out;
}

namespace {
Interpreter::BlockView view_of(const Block& block) {
  Interpreter::BlockView b;
  b.o_name = block.o_name;
  b.params = block.call_args;
  b.g_modes.assign(block.g.begin(), block.g.end());
  b.m_modes.assign(block.m.begin(), block.m.end());
  return b;
}
}  // namespace

Interpreter::BlockView Interpreter::current_block() const { return view_of(s_->block); }

std::vector<Interpreter::BlockView> Interpreter::remap_blocks() const {
  const State& s = *s_;
  std::vector<const RemapCall*> calls;
  for (const Frame& f : s.frames) {
    if (f.remap) calls.push_back(f.remap.get());
  }
  for (const auto& rc : s.python_remaps) calls.push_back(rc.get());
  std::sort(calls.begin(), calls.end(), [](const RemapCall* a, const RemapCall* b) { return a->seq < b->seq; });
  std::vector<BlockView> out;
  for (const RemapCall* rc : calls) out.push_back(view_of(rc->block));
  return out;
}

Status Interpreter::execute_script_line(std::string_view line) {
  State& s = *s_;
  const std::string text(line);
  const std::string what = "self.execute(\"" + text + "\")";
  if (text.find('\n') != std::string::npos) {
    throw InterpError(what + ": runs one line (without a line end)", s.current_file, s.current_line, s.line_text);
  }
  if (s.synch_pending) {
    throw InterpError(what + ": the line run before needs the machine to catch up first (yield "
                          "INTERP_EXECUTE_FINISH after it)",
                      s.current_file, s.current_line, s.line_text);
  }
  // The block being executed and the place in the program, restored after
  // the line ran (or failed).
  const Block block = s.block;
  const bool block_ready = s.block_ready;
  const int exec_step = s.exec_step;
  const bool resume_block = s.resume_block;
  const int current_line = s.current_line;
  const std::string current_file = s.current_file, line_text = s.line_text, norm = s.norm;
  const int64_t line_offset = s.line_offset;
  const std::size_t o_args_pos = s.o_args_pos;
  const int n_number = s.n_number, lines_this_read = s.lines_this_read;
  State::PendingStage stage = std::move(s.stage);
  s.stage = {};
  const std::size_t files_depth = s.files.size(), frames_depth = s.frames.size(), python_depth = s.python_remaps.size();
  const auto restore = [&] {
    s.block = block;
    s.block_ready = block_ready;
    s.exec_step = exec_step;
    s.resume_block = resume_block;
    s.current_line = current_line;
    s.current_file = current_file;
    s.line_text = line_text;
    s.norm = norm;
    s.line_offset = line_offset;
    s.o_args_pos = o_args_pos;
    s.n_number = n_number;
    s.lines_this_read = lines_this_read;
    s.stage = std::move(stage);
    --s.script_line_depth;
  };
  ++s.script_line_depth;
  Status last = Status::Ok;
  try {
    SourceFile f;
    f.reader = std::make_unique<LineReader>(LineReader::from_string(text));
    f.path = "<mdi>";
    s.push_source(std::move(f));
    for (;;) {
      s.lines_this_read = 0;
      const ReadResult rr = s.read_block();
      if (rr == ReadResult::Yield) continue;
      if (rr == ReadResult::End) break;
      last = s.execute_ready();
      if (last == Status::ProgramEnd) s.fail(what + ": a program end cannot run from a script");
      // Waiting inside a subroutine the line called: the lines after it
      // would be read before the machine caught up.
      if (last == Status::ExecuteFinish && s.frames.size() > frames_depth) {
        s.fail(what + ": needs the machine to catch up before the subroutine it called ends (a script can wait "
                      "only after the line: yield INTERP_EXECUTE_FINISH)");
      }
      if (s.files.size() <= files_depth) break;
    }
  } catch (...) {
    // Leave what the line started: its calls, files and Python bodies.
    while (s.frames.size() > frames_depth) {
      Frame fr = std::move(s.frames.back());
      s.frames.pop_back();
      if (!fr.fanuc) {
        for (int k = 0; k < 30; ++k) s.params[static_cast<std::size_t>(k + 1)] = fr.saved_args[static_cast<std::size_t>(k)];
      }
      while (static_cast<int>(s.files.size()) > fr.file_depth) s.pop_source();
      if (!s.files.empty()) s.jump(fr.return_offset, fr.return_line);
    }
    while (s.files.size() > files_depth) s.pop_source();
    s.python_remaps.resize(python_depth);
    s.skipping = false;
    s.skip_defining = false;
    restore();
    throw;
  }
  while (s.files.size() > files_depth) s.pop_source();
  restore();
  if (last == Status::ExecuteFinish) s.synch_pending = true;
  return last;
}

std::vector<int> Interpreter::active_m_codes() const {
  const State& s = *s_;
  std::vector<int> m;
  m.push_back(s.spindle == Direction::Clockwise ? 3 : s.spindle == Direction::CounterClockwise ? 4 : 5);
  if (s.mist) m.push_back(7);
  if (s.flood) m.push_back(8);
  if (!s.mist && !s.flood) m.push_back(9);
  m.push_back(s.feed_override && s.speed_override ? 48 : 49);
  return m;
}

Pose Interpreter::position() const { return s_->pos; }

}  // namespace cnc::interp
