// RS274/NGC interpreter (LinuxCNC's G-code dialect): reads a program block by
// block, keeps the modal state, and calls a Canon for every machining effect.
// Non-realtime (task controller side); errors throw InterpError carrying the
// line and LinuxCNC's wording. Files are streamed, never loaded whole.
//
// Read-ahead and synchronisation: execute() returns Status::ExecuteFinish
// after a block whose result depends on the machine (probe, M66 input wait,
// tool change M6, M61). The caller must then
// let the machine finish everything queued and call synch() before the next
// read(); until it does, read() returns Status::SynchRequired and reads
// nothing. synch() re-reads position, probe result, input value and the tool
// table through the Canon queries.
//
// Bounded work: one read() reads at most Config::lines_per_read lines; when
// they were all O-word flow, assignments, comments or skipped lines it
// returns Status::Yield and the caller calls read() again when it likes (the
// task controller in its next cycle). More than
// Config::max_blocks_without_output lines in a row without machine output is
// an error naming the file and line (an endless loop), counted in lines so
// that the outcome never depends on the speed of the computer.
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "core/interp/canon.hpp"

namespace cnc::ini {
class IniFile;
}

namespace cnc::interp {

// An interpreter error: LinuxCNC's message text, the file and line.
class InterpError : public std::runtime_error {
 public:
  InterpError(std::string message, std::string file, int line, std::string block_text);
  const std::string& message() const noexcept { return message_; }
  const std::string& file() const noexcept { return file_; }
  int line() const noexcept { return line_; }
  const std::string& block_text() const noexcept { return block_text_; }

 private:
  std::string message_;
  std::string file_;
  int line_;
  std::string block_text_;
};

enum class Status {
  Ok,             // block read/executed; go on
  ExecuteFinish,  // executed; machine must finish, then synch() before read()
  SynchRequired,  // read() refused: call synch() first
  ProgramEnd,     // M2/M30 executed, or end of file after %
  EndOfFile,      // no more blocks (file ended without M2/% ); for MDI: the line is done
  Yield,          // read() read lines_per_read lines and no block yet: call read() again
};
const char* to_string(Status s) noexcept;

// One [RS274NGC]REMAP= line: a G or M code (or T, S, F) whose execution
// calls O-word subroutines instead of (or, inside them, as) the built-in.
struct RemapSpec {
  char letter = 'm';   // 'g', 'm', 't', 's' or 'f'
  int code = 0;        // G x10 (881 for G88.1), the M number; 0 for T, S, F
  int modal_group = 10;  // where in the block it runs: 1 (G motion), 4-10 (M)
  std::string argspec;   // LinuxCNC's: A-Z required, a-z optional, @ positional, > feed, ^ speed
  std::string ngc;       // the body: o<ngc> (found as ngc.ngc in SUBROUTINE_PATH)
  std::string python;    // py=: the body is this Python function of module `remap` ("" none)
  std::string prolog;    // called before the body ("" none): a subroutine, or
  std::string epilog;    // after it: Python functions of `remap` when *_python
  bool prolog_python = false;
  bool epilog_python = false;
  std::string where;     // "file:line" of the REMAP= line
  std::string name() const;  // "M400", "G88.1", "T"
};

class Interpreter;

// Embedded scripts ([PYTHON], core/interp/python/python_host.hpp): O-word
// subroutines written as functions of the script's `oword` module, and
// statements in `;py,` and `(py,...)` comments. The interpreter knows only
// this interface; the script library implements it.
class ScriptHost {
 public:
  virtual ~ScriptHost() = default;
  // Interpreter::init(): the interpreter the scripts see as
  // `interpreter.this` (and `self`); runs the start-up script once.
  virtual void attach(Interpreter& interp, Canon& canon) = 0;
  // True when `name` (as written after o<, lower case) is a script function.
  virtual bool has_oword(const std::string& name) = 0;
  // Calls it with the call's arguments; the number it returned, if any.
  // Throws std::runtime_error with the script's error.
  virtual std::optional<double> call_oword(const std::string& name, const std::vector<double>& args) = 0;
  // Runs the statement of a `py,` comment. Throws std::runtime_error.
  virtual void run_statement(const std::string& code) = 0;
  // True when `name` is a function of the module bound to `remap`.
  virtual bool has_remap(const std::string& name) = 0;
  // What a REMAP's Python stage did: `error` empty when it succeeded (else
  // the message it set with self.set_errormsg() when it returned
  // INTERP_ERROR, or what went wrong); `waits` when it is a generator that
  // yielded INTERP_EXECUTE_FINISH: it is suspended until resume_remap().
  struct RemapOutcome {
    std::string error;
    bool waits = false;
  };
  // A REMAP's Python body, prolog or epilog: name(self, **words); a
  // generator runs to its first yield. Throws std::runtime_error for a
  // Python exception.
  virtual RemapOutcome call_remap(const std::string& name, const std::vector<std::pair<std::string, double>>& words) = 0;
  // Resumes the stage suspended last (to its next yield or its end); the
  // interpreter calls it after the machine caught up. Throws
  // std::runtime_error for a Python exception (the stage is dropped).
  virtual RemapOutcome resume_remap() { return {"no remap procedure is waiting to be resumed", false}; }
  // Forgets the stages suspended after the `keep` oldest (abort, reset, an
  // error while they waited).
  virtual void drop_suspended_remaps(std::size_t keep = 0) { (void)keep; }
  virtual std::size_t suspended_remaps() const { return 0; }
  // Predefined named parameters computed by a script (LinuxCNC's module
  // `namedparams`: its functions whose names start with '_'), sorted.
  virtual std::vector<std::string> script_parameters() { return {}; }
  // The value of one of them (false when `name` is none); throws
  // std::runtime_error with the script's error.
  virtual bool script_parameter(const std::string& name, double& value) {
    (void)name;
    (void)value;
    return false;
  }
};

struct Config {
  // [RS274NGC]PARAMETER_FILE; empty: no persistence.
  std::filesystem::path parameter_file;
  // [RS274NGC]SUBROUTINE_PATH (colon separated in the INI), searched for
  // "name.ngc" when a subroutine is not defined in the program.
  std::vector<std::filesystem::path> subroutine_path;
  // [RS274NGC]USER_M_PATH: folders searched for M100-M199 programs. Empty:
  // user M codes are unknown ("off unless configured").
  std::vector<std::filesystem::path> user_m_path;
  // [RS274NGC]RS274NGC_STARTUP_CODE, executed by init().
  std::string startup_code;
  // [EMCIO]RANDOM_TOOLCHANGER
  bool random_toolchanger = false;
  // [RS274NGC]CENTER_ARC_RADIUS_TOLERANCE_INCH/_MM: how much the radius to
  // the end of a centre-format arc may differ from the radius to its start
  // (absolutely; more than 100 times this, or more than this and by more
  // than 0.1 %, is an error). LinuxCNC's defaults, 2 * 0.001 inch * sqrt(2)
  // and 2 * 0.01 mm * sqrt(2) (end and centre rounded to 0.001 inch or 0.01
  // mm pass), are also the largest values allowed; the smallest are 0.00004
  // inch and 0.001 mm.
  double center_arc_radius_tolerance_inch = kDefaultCenterArcToleranceInch;
  double center_arc_radius_tolerance_mm = kDefaultCenterArcToleranceMm;
  static constexpr double kDefaultCenterArcToleranceInch = 2 * 0.001 * 1.41421356237309504880;
  static constexpr double kDefaultCenterArcToleranceMm = 2 * 0.01 * 1.41421356237309504880;
  static constexpr double kMinCenterArcToleranceInch = 0.00004;
  static constexpr double kMinCenterArcToleranceMm = 0.001;
  // [TRAJ]SPINDLES: spindles 0..spindles-1, chosen with the $ word.
  int spindles = 1;
  static constexpr int kMaxSpindles = 8;
  // Axes the machine has (bit i: axis i of XYZABCUVW).
  unsigned axis_mask = 0x1ff;
  // Length units the interpreter starts in.
  Units default_units = Units::Mm;
  // INI for #<_ini[section]key>; may be null.
  const cnc::ini::IniFile* ini = nullptr;
  // Lathe: start in diameter mode (G7).
  bool lathe_diameter_mode = false;
  // [RS274NGC]DISABLE_G92_PERSISTENCE: the G92/G52 offset (#5210-#5219)
  // is cleared at start and at program end instead of being kept.
  bool disable_g92_persistence = false;
  // [RS274NGC]ORIENT_OFFSET: degrees added to M19's R (0..360).
  double orient_offset = 0;
  // [EMCIO]TOOL_CHANGE_WITH_SPINDLE_ON: M6 leaves the spindle running.
  bool tool_change_with_spindle_on = false;
  // Block delete switch ('/' lines skipped when on).
  bool block_delete = false;
  // The informational COMMENT calls LinuxCNC emits ("interpreter: feed mode
  // set to ...", "... cutter radius compensation on left", ...).
  bool linuxcnc_comments = true;
  // [RS274NGC]MAX_BLOCKS_WITHOUT_OUTPUT: lines read in a row (O-word flow,
  // assignments, comments, lines skipped by if/while, subroutine lines)
  // without any machine output (motion, dwell, spindle, coolant, tool,
  // digital/analog output, input wait, stop, user M code) or synch(); one
  // more is the error "... an endless loop?" naming the file and line.
  int64_t max_blocks_without_output = 10'000'000;
  // Lines one read() call reads at most before it returns Status::Yield
  // (not an INI key: it bounds the work per call, not what a program may do).
  int lines_per_read = 256;
  // #<_task>: 1 when the interpreter runs in the task controller, 0 in a
  // preview or the stand-alone tool (LinuxCNC's rs274 -T sets it).
  bool task = false;

  // [RS274NGC]REMAP lines, in file order (docs/interpreter.md, "REMAP").
  std::vector<RemapSpec> remaps;
  // [RS274NGC]OWORD_NARGS: an O-word call sets #<n_args> in the subroutine
  // to the number of arguments it was given.
  bool oword_nargs = false;
  // [RS274NGC]DISABLE_FANUC_STYLE_SUB: M98/M99 and O-number subprograms
  // (O1000 ... M99) are refused.
  bool disable_fanuc_style_sub = false;
  // Embedded scripts; null: none (`py,` comments are plain comments and
  // only G-code subroutines exist).
  std::shared_ptr<ScriptHost> script;
  // Fills the fields above from [RS274NGC], [EMCIO] and [TRAJ]; a bad REMAP
  // line throws ConfigError naming its file and line.
  static Config from_ini(const cnc::ini::IniFile& ini);
};

class Interpreter {
 public:
  Interpreter(Canon& canon, Config config = {});
  ~Interpreter();
  Interpreter(const Interpreter&) = delete;
  Interpreter& operator=(const Interpreter&) = delete;

  // Resets all state to power-on defaults, loads the parameter file, calls
  // the Canon's initial calls and runs the start-up code.
  void init();
  // Back to the state after init() but keeps parameters; closes the
  // program. Used on abort.
  void reset();

  // Opens a program file; throws InterpError when it cannot be read.
  void open(const std::filesystem::path& program);
  // Run-from-line: opens the program and positions reading at `line`
  // (1-based). Subroutine definitions before the line are learned but
  // nothing is executed; the task controller reconstructs modal state.
  void open_at_line(const std::filesystem::path& program, int line);
  void close();
  bool is_open() const noexcept;

  // Reads the next block of the open program (with O-word flow). Ok: a
  // block is ready for execute(); Yield: lines_per_read lines were read
  // without finding one, call read() again. Throws InterpError.
  Status read();
  // Starts reading an MDI line instead of the program (the line is read
  // from a source above the program). Ok: a block is ready; Yield: call
  // read(). Later read() calls go on with the line and any subroutine it
  // called, stepwise like a program, until they return EndOfFile (or
  // ProgramEnd): the MDI line is done.
  Status read(std::string_view mdi_line);
  // Executes the block last read. Throws InterpError.
  Status execute();
  // read(line) then execute() and whatever subroutine it calls, to the end,
  // synchronising at once at synch points (start-up code, offset lines,
  // tools and tests; the task controller reads MDI stepwise instead).
  Status execute(std::string_view mdi_line);
  // After an InterpError: leaves every subroutine call in progress and goes
  // on at the top level after the outermost call, drops the moves cutter
  // compensation held back and any skip in progress (LinuxCNC's
  // unwind_call; `rs274 -n 0` goes on after an error so). The modal state
  // and the parameters stay as they are.
  void unwind();
  // The subroutine calls in progress, outermost first, as "o<name> called
  // at file:line" (for `rs274 -s`).
  std::vector<std::string> call_stack() const;
  // Re-reads the machine state after the machine caught up.
  void synch();
  bool is_synch_pending() const noexcept;

  // Runs the whole open program to the end, calling synch() at every
  // synch point and reading on after every Yield (for tools, tests and
  // benchmarks where the Canon answers at once). Returns ProgramEnd or
  // EndOfFile.
  Status run_to_end();

  // Writes the persistent parameters to the parameter file (atomically)
  // when they changed since it was read or last written; throws FileError
  // (core/util/atomic_file.hpp) when it cannot be written.
  void save_parameters() const;

  // Line number (1-based) of the block last read; 0 for MDI.
  int line() const noexcept;
  // Number of the block's N word, -1 when none.
  int n_number() const noexcept;
  const std::string& file_name() const noexcept;
  // Subroutine call depth (0 at top level).
  int call_level() const noexcept;
  // Remapped codes being carried out (#<_remap_level>).
  int remap_level() const noexcept;
  // The speed last set for spindle k (0 .. Config::kMaxSpindles-1).
  double spindle_speed(int k) const noexcept;

  // Numbered and named parameter access (for tools and tests).
  double parameter(int index) const;
  void set_parameter(int index, double value);
  bool named_parameter(std::string_view name, double& value) const;
  // Sets a named parameter as `#<name> = value` does (global when it starts
  // with '_', else local to the current call); throws InterpError for a
  // read-only one.
  void set_named_parameter(std::string_view name, double value);
  // The tool table as the interpreter knows it (index 0: the spindle) and
  // the tool length offset in effect (program units).
  const cnc::tooltable::ToolTable& tool_table() const noexcept;
  Pose tool_offset() const noexcept;
  // The Canon the interpreter calls (embedded scripts make calls on it).
  Canon& canon() noexcept;

  // The active G and M codes as LinuxCNC reports them (G x10, e.g. 641 for G64.1).
  std::vector<int> active_g_codes() const;
  // A named parameter as LinuxCNC's sub_context lists it; attr holds its
  // PA_* bits (1 read-only, 2 global, 16 from the INI file, 32 computed by
  // a script).
  struct NamedParameter {
    std::string name;
    double value = 0;
    int attr = 0;
  };
  // The named parameters of call level `level`, sorted by name: level 0
  // the predefined ones (LinuxCNC 2.9's list, INI values read so far, the
  // script's), the globals and the top level's locals; above, that call's
  // locals. Script parameters are listed with the value 0 (not computed).
  std::vector<NamedParameter> named_parameters(int level) const;
  // The block being executed, as scripts see it (LinuxCNC's blocks[0]).
  struct BlockView {
    std::string o_name;
    std::vector<double> params;  // an O-word call's arguments
    std::vector<int> g_modes, m_modes;
  };
  BlockView current_block() const;
  std::vector<int> active_m_codes() const;
  Pose position() const;  // program coordinates, program units

  // Runs `line` for an embedded script (LinuxCNC's self.execute()): the
  // line and whatever it calls (subroutines, remapped codes) to the end,
  // inside the block being executed. ExecuteFinish: its last block needs
  // the machine to catch up; the script must wait (yield
  // INTERP_EXECUTE_FINISH) before it runs another line. A synch point
  // before the end, a program end, or a Python remap procedure in it that
  // waits for the machine is an InterpError (a script cannot wait in the
  // middle of a line it runs); the interpreter's place in the program is
  // kept after an error too.
  Status execute_script_line(std::string_view line);
  // The blocks of the remapped codes being carried out (LinuxCNC's
  // blocks[1..remap_level]), outermost first.
  std::vector<BlockView> remap_blocks() const;

  struct State;

 private:
  std::unique_ptr<State> s_;
};

}  // namespace cnc::interp
