// Interpreter::State: everything the interpreter knows, and the member
// functions the .cpp files of this folder implement (read.cpp: lexing and
// expressions; flow.cpp: O-words and files; execute.cpp: blocks; motion.cpp:
// moves, arcs, cycles, cutter compensation; params.cpp: parameters).
#pragma once

#include <set>
#include <string_view>

#include "core/interp/queueing_canon.hpp"
#include "core/interp/state.hpp"

namespace cnc::interp {

// What read_block() found: a block to execute, the end of the input, or
// nothing yet after Config::lines_per_read lines.
enum class ReadResult : uint8_t { Block, End, Yield };

struct Interpreter::State {
  State(Canon& c, Config cfg);

  QueueingCanon queueing;  // holds calls back behind a compensated move
  Canon& canon;            // = queueing; queueing.real() is the caller's Canon
  Config config;

  // ---------------- sources and flow
  std::vector<SourceFile> files;
  int next_source_id = 1;
  void push_source(SourceFile f);
  void pop_source();
  std::string program_path;
  std::string program_display_name;  // the name as given to open()
  bool percent_seen = false;   // first line was '%'
  bool first_line = true;
  bool program_ended = false;
  std::unordered_map<std::string, SubDef> subs;
  std::vector<Frame> frames;  // frames[0] is the top level
  // Skipping: read lines until one of these o-words with this label.
  bool skipping = false;
  std::string skip_label;
  uint32_t skip_types = 0;  // bit per OType
  bool skip_defining = false;  // skipping a sub definition body
  std::string line_text;   // raw text of the block being read
  std::string norm;        // normalized (lower case, no blanks) text
  int current_line = 0;
  int64_t line_offset = 0;  // offset of the line being read
  std::size_t o_args_pos = 0;  // where an O-word's condition/arguments start in norm
  std::string current_file;

  // ---------------- bounded work
  int lines_this_read = 0;           // lines read by this read() call
  int64_t lines_without_output = 0;  // lines read since machine output or synch()
  uint64_t outputs_seen = 0;         // queueing.outputs() when last compared
  // Counts the line just read; fails past config.max_blocks_without_output.
  void count_line();
  // The machine was waited for (synch), or a new program or MDI command
  // starts: the count of lines without output starts again.
  void machine_waited() noexcept {
    lines_without_output = 0;
    outputs_seen = queueing.outputs();
  }

  // ---------------- the block
  Block block;
  bool block_ready = false;
  bool synch_pending = false;

  // ---------------- parameters
  std::vector<double> params;
  std::unordered_map<std::string, double> globals;
  std::vector<bool> persistent;  // per numbered parameter

  // ---------------- modal state
  Pose pos{};  // program coordinates, program units
  Units units = Units::Mm;
  Plane plane = Plane::XY;
  bool absolute = true;
  bool ijk_absolute = false;
  FeedMode feed_mode = FeedMode::UnitsPerMinute;
  double feed = 0;
  double speed = 0;
  Direction spindle = Direction::Stopped;  // spindle 0; `speed`, `css`, `css_max` too
  // Spindles 1.. ([TRAJ]SPINDLES, the $ word); index 0 unused (the fields above).
  struct OtherSpindle {
    double speed = 0;
    Direction dir = Direction::Stopped;
    bool css = false;
    double css_max = 0;
  };
  std::array<OtherSpindle, Config::kMaxSpindles> other_spindles{};
  // The spindles a block's $ word chooses (absent: 0; $-1: all), checked
  // against [TRAJ]SPINDLES; `what` names the command in the error.
  std::vector<int> chosen_spindles(const char* what, bool minus_one_allowed = true) const;
  void set_speed(int k, double rpm);
  void set_direction(int k, Direction d);
  // LinuxCNC's active spindle: chosen by $ (or 0 without) with G93-G95 and
  // G96/G97, by $ with G33, G33.1, G76; feed per revolution and
  // spindle-synchronised motion follow it.
  int active_spindle = 0;
  // The spindle a block's $ names for `what` (a single spindle, not $-1).
  int chosen_spindle(const char* what) const { return chosen_spindles(what, false).front(); }
  double active_speed() const {
    return active_spindle == 0 ? speed : other_spindles[static_cast<std::size_t>(active_spindle)].speed;
  }
  Direction active_direction() const {
    return active_spindle == 0 ? spindle : other_spindles[static_cast<std::size_t>(active_spindle)].dir;
  }
  bool css = false;
  double css_max = 0;
  bool mist = false, flood = false;
  int motion_mode = 0;  // G x10; -1 for G80
  int origin = 1;       // 1..9 = G54..G59.3
  Pose origin_offset{};  // program units
  Pose axis_offset{};    // G92, program units
  double rotation = 0;   // degrees (G10 L2 R)
  Pose tool_offset{};    // program units
  int tool_offset_g = 490;  // 430, 431, 432, 490
  MotionMode control = MotionMode::ExactPath;
  double tolerance = 0, naive_tolerance = 0;
  bool retract_old_z = true;  // G98
  bool feed_override = true, speed_override = true, adaptive = false, feed_hold = true;
  bool diameter_mode = false;
  int selected_tool = -1;   // T number
  int selected_index = -1;  // tooldata index
  int current_index = 0;    // tooldata index the spindle tool came from
  bool toolchange_flag = false;
  cnc::tooltable::ToolTable tools;
  int cutter_side = 400;  // 400 off, 410 left, 420 right
  double cutter_radius = 0;
  int cutter_orientation = 0;
  bool cutter_first_move = true;
  bool comp_exit_move = false;  // G40 ended compensation: the next move must be straight
  Pose comp_program_pos{};
  // Where the held-back move starts in the plane (tool centre), when known:
  // the gouge checks of a corner compare the move's new end with it.
  double comp_start1 = 0, comp_start2 = 0;
  bool comp_start_valid = false;
  // canned cycles
  double cycle_r = 0, cycle_z = 0, cycle_cc = 0;
  int cycle_l = 1;
  bool nurbs_active = false;  // between G5.2 and G5.3
  int nurbs_order = 3;
  std::vector<Canon::ControlPoint> nurbs_points;
  double polar_end_x = 0, polar_end_y = 0;  // end point of this block's @/^ words
  double spline_last_p = 0, spline_last_q = 0;  // G5 without I/J mirrors these
  double cycle_il = 0;  // initial level of a run of cycle blocks
  bool cycle_il_valid = false;
  double cycle_p = 0, cycle_q = 0, cycle_i = 0, cycle_j = 0, cycle_k = 0;
  // probe / input results
  Pose probe_pos{};
  bool probe_ok = false;
  bool probe_pending = false;
  bool input_pending = false;
  double input_result = 0;
  int n_number = -1;

  // ---------------- read.cpp
  ReadResult read_block();
  bool next_raw_line(std::string_view& text);
  void parse_line(std::string_view raw);
  void normalize(std::string_view raw);
  void parse_words(std::size_t& i);
  void read_word(std::size_t& i);
  void read_o_word(std::size_t& i);
  void read_parameter_setting(std::size_t& i);
  void read_comment(std::size_t& i);
  double read_real_value(std::size_t& i);
  double read_real_number(std::size_t& i);
  double read_expression(std::size_t& i);
  double read_unary(std::size_t& i);
  double read_parameter(std::size_t& i, bool for_exists = false);
  int read_integer_value(std::size_t& i);
  std::string read_name(std::size_t& i);
  void add_g(int code);
  void add_m(int code);
  [[noreturn]] void fail(const std::string& message) const;

  // ---------------- params.cpp
  void init_parameters();
  void load_parameter_file();
  // Writes the persistent parameters atomically when they differ from what
  // the file holds; throws FileError when the file cannot be written.
  void save_parameter_file() const;
  std::string parameter_text() const;
  mutable std::string saved_parameters_;  // what the parameter file holds
  double get_param(int index) const;
  void set_param(int index, double value, bool check_readonly);
  double get_named(const std::string& name) const;
  bool find_named(const std::string& name, double& value) const;
  void set_named(const std::string& name, double value);
  bool predefined(const std::string& name, double& value) const;
  mutable std::set<std::string> ini_names_read;  // #<_ini[s]k> names read so far (listed as predefined)
  void write_position_params();
  void write_tool_params();
  std::string substitute_params(std::string_view text);

  // ---------------- flow.cpp
  void open_file(const std::string& path);
  bool handle_o_word();  // true when the line needs no further execution
  void check_label_unique(const std::string& label);
  std::unordered_map<std::string, int> o_label_lines;  // file+sub+label -> line it opened at
  bool skip_line_matches(std::string_view raw);
  bool skip_line_matches_sub(std::string_view raw, const std::string& label);
  void start_skip(const std::string& label, std::initializer_list<OType> types, bool defining = false);
  // An O-word call (o<name> call), or with fanuc an M98 run `repeats` times.
  void do_call(bool fanuc = false, int repeats = 1);
  void convert_fanuc_call();
  void convert_fanuc_return(Status& st);
  void do_return(bool has_value, double value);
  std::optional<std::string> find_sub_file(const std::string& name) const;
  Frame& frame() { return frames.back(); }
  void jump(int64_t offset, int line_before);

  // ---------------- remapping (execute.cpp)
  int exec_step = 0;          // execute_block() starts at this step (after a remap returned)
  bool resume_block = false;  // a remap returned: read_block() hands the block back
  // The REMAP of a code, unless it is being carried out already (then the
  // code is the built-in, as in LinuxCNC).
  const RemapSpec* find_remap(char letter, int code, bool active_too = false) const;
  const RemapSpec* remap_at_step(int step) const;
  int remap_level() const;
  void check_remap_args();
  // Starts carrying out the remapped code of `step`; returns what the
  // block returns: at a subroutine call the block stops (`st`, read goes on
  // in the procedure); a Python body runs now and the block goes on after
  // it; ExecuteFinish when a Python stage waits for the machine.
  Status start_remap(const RemapSpec& spec, int step, Status st);
  // A Python stage of a remap (prolog, body or epilog), called or resumed;
  // an error (with `block_text` as the error's block when not empty) is an
  // InterpError. True when it waits for the machine (a generator yielded
  // INTERP_EXECUTE_FINISH): `stage` then says what to resume.
  enum class StageKind : uint8_t { None, Prolog, Body, Epilog };
  bool python_stage(StageKind kind, const std::shared_ptr<RemapCall>& rc, bool resume);
  // What execute() does instead of a block: a Python stage to run (an
  // epilog met at the body's endsub) or to resume after the machine caught up.
  struct PendingStage {
    StageKind kind = StageKind::None;
    bool resume = false;
    std::shared_ptr<RemapCall> rc;
    bool has_value = false;  // an epilog's endsub/return value
    double value = 0;
  };
  PendingStage stage;
  // Runs a Python stage and what follows it once it ends (the next stage,
  // the body's subroutine call, the return, the rest of the block).
  Status run_stage(PendingStage p);
  std::vector<std::shared_ptr<RemapCall>> python_remaps;  // remaps with a Python body being carried out
  int remap_seq = 0;           // numbers RemapCall::seq
  int script_line_depth = 0;   // execute_script_line() calls in progress
  // execute(): the pending stage, else the block read.
  Status execute_ready();
  void call_remap_stage(const std::shared_ptr<RemapCall>& rc);
  bool remap_returned(const std::shared_ptr<RemapCall>& rc);
  // Forgets the remap stages waiting (abort, reset, open).
  void drop_stages();

  // ---------------- execute.cpp
  Status execute_block();
  void execute_step(int step, Status& st);
  void reset_modal(bool keep_params);
  void canon_init_calls();
  void convert_comment();
  // A `py,` statement on the configured ScriptHost (none: ignored as a
  // comment); a script error is an InterpError of the line.
  void run_script(const std::string& code);
  void convert_feed_mode(int g);
  void convert_spindle_mode(int g);
  void convert_m(int group, Status& st);
  void convert_g();
  void convert_g_motion(Status& st);
  void convert_stop(Status& st);
  void convert_tool_select();
  void convert_tool_change(Status& st);
  void convert_tool_length_offset(int g);
  void convert_setup_tool(int l);
  void convert_coord_setup(int l);
  void convert_coordinate_system(int g);
  void load_origin(int system, const Pose& moved);
  void convert_axis_offsets(int g);
  void convert_home(int g);
  void convert_units(Units u);
  void convert_plane(int g);
  void convert_control_mode(int g);
  void convert_cutter_comp(int g);
  void convert_dwell();
  void set_distance_mode(bool abs);
  void set_tool_offset_params();
  void end_program(bool pallet);
  double to_program_len(double machine_len) const;
  double to_machine_len(double program_len) const;
  double to_program_axis(int axis, double machine_value) const;  // lengths scaled, A B C not
  double to_machine_axis(int axis, double program_value) const;
  void snapshot_modal(ModalSnapshot& s) const;
  void restore_modal(const ModalSnapshot& s);
  void update_tool_from_canon();

  // ---------------- motion.cpp
  void convert_motion(int g, Status& st);
  void convert_polar();
  Pose find_ends(bool g53) const;
  Pose current_in_system(int system, bool without_tool) const;
  Pose program_to_machine(const Pose& p) const;
  Pose machine_to_program(const Pose& m) const;
  void straight(int g, const Pose& end);
  void convert_arc(int g, const Pose& end);
  void convert_probe(int g, const Pose& end, Status& st);
  void convert_threading(int g, const Pose& end);
  void convert_cycle(int g, Pose end);
  void convert_g76(const Pose& end);
  // G70/G71/G72 (lathe_cycles.cpp): the contour is read from the Q subroutine.
  void convert_g7x(int g);
  int capture_depth = -1;  // >= 0 while G7x reads its contour: read_block() ends when the call returns to this depth
  void convert_spline(int g, const Pose& end);
  void convert_nurbs(int g);
  void check_other_words() const;
  void emit_traverse(const Pose& p);
  void emit_feed(const Pose& p);
  void inverse_time_feed_straight(const Pose& from, const Pose& to);
  void inverse_time_feed_arc(double length);
  void plane_axes(int& a1, int& a2, int& a3) const;
  double arc_tolerance() const;     // centre-format radius difference
  double radius_tolerance() const;  // smallest radius, R-format reach
  // cutter comp
  void comp_straight(bool traverse, const Pose& end);
  void comp_arc(int g, const Pose& end, double c1, double c2, int turns);
  void comp_flush();
  void comp_emit(const CompMove& m);
  void hold_move(const CompMove& m);
  void comp_set_start(double s1, double s2);
  void comp_move_end(double e1, double e2);
};

const char* plane_name(Plane p);
// Modal group of a built-in G (x10) or M code, -1 when it is none.
int builtin_g_group(int code);
int builtin_m_group(int code);
void rotate_xy(double& x, double& y, double degrees);

}  // namespace cnc::interp
