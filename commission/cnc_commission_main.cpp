// cnc-commission: the commissioning steps as subcommands for people and
// scripts, over the commissioning library (docs/commissioning.md). Every
// subcommand reads the state file, does its step and saves the state.
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cerrno>
#include <cstring>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "commission/backup.hpp"
#include "commission/restore.hpp"
#include "core/ipc/client.hpp"
#include "fieldbus/ethercat/master.hpp"
#include "commission/check.hpp"
#include "commission/comp_camera.hpp"
#include "commission/compensation.hpp"
#include "commission/config_writer.hpp"
#include "commission/controller.hpp"
#include "commission/lss_assign.hpp"
#include "commission/hold_to_run.hpp"
#include "commission/homing_check.hpp"
#include "commission/switches.hpp"
#include "commission/scan.hpp"
#include "commission/state.hpp"
#include "commission/steps.hpp"
#include "core/util/atomic_file.hpp"
#include "commission/tuning.hpp"
#include "commission/response.hpp"
#include "core/util/strings.hpp"
#include "fieldbus/can/transport.hpp"

namespace {

using namespace cnc::commission;

const char* kHelp =
    "usage: cnc-commission [--state FILE] COMMAND ...\n"
    "Commissioning of a machine's drives, one step at a time; each step keeps\n"
    "its results in the state file (default commission.json) so that work can\n"
    "be left and resumed.\n"
    "\n"
    "commands:\n"
    "  scan --interface SPEC [--bitrate BIT/S] [--eds-dir DIR] [--expect ID,ID..]\n"
    "       [--first ID] [--last ID] [--timeout-ms MS]\n"
    "      scan the CANopen bus (socketcan:can0): identity, name, firmware, CiA 402\n"
    "      modes, faults, encoder and gear objects; match each node with an EDS\n"
    "  lss --interface SPEC [--first ID] [--bitrate BIT/S] [--window-ms MS]\n"
    "      give every device without node-ID one (LSS fastscan, CiA 305), from ID up,\n"
    "      skipping the node-IDs the last scan found; the devices store it\n"
    "  scan-ethercat --interface raw:IF [--esi-dir DIR]\n"
    "      scan the EtherCAT segment: each slave's SII identity, CoE, DC; match each\n"
    "      with an ESI file\n"
    "  show\n"
    "      print the state: nodes, axes, scaling, tests\n"
    "  axis L assign (--node ID | --slave POSITION) [--joint J]\n"
    "      [--gantry-node ID | --gantry-slave POSITION] [--gantry-joint J] [--gantry-reverse]\n"
    "      drive node ID moves axis L (X Y Z A B C U V W) on joint J; a gantry: the\n"
    "      second drive of the axis on its own joint (the next free one unless given)\n"
    "  axis L scaling --lead MM [--counts N] [--gear MOTOR:LOAD]\n"
    "      screw lead; counts per revolution and gear from the drive unless given\n"
    "  axis L limits --min MM --max MM [--velocity MM/S] [--acceleration MM/S2]\n"
    "      soft limits (the travel tune and comp-run may use until the switches are\n"
    "      found) and the axis' speed and acceleration\n"
    "  axis L direction-test [--distance MM] [--velocity MM/S] [--dial MM] [--dial2 MM]\n"
    "                        [--hold] [--bin DIR] [--bring-up DIR]\n"
    "      jog the axis on the running controller (at most 2 mm until a dial reading\n"
    "      checked the scaling, then 20 mm; at most 5 mm/s; time-limited, switched off\n"
    "      afterwards) and compare the drive's feedback; a gantry pair: both joints\n"
    "      jogged together, --dial2 the second side's reading;\n"
    "      --hold: hold-to-run, the jog starts when a key is pressed and stops when\n"
    "      it is let go (the key's auto-repeat stops: 1 s after the first press,\n"
    "      0.25 s after a repeat), as Ctrl-C stops it;\n"
    "      --bring-up writes the configuration of the state to DIR and runs the\n"
    "      test on a controller of its own, shut down afterwards\n"
    "  axis L tune [--max-velocity MM/S] [--max-acceleration MM/S2] [--margin PCT]\n"
    "              [--record DIR] [--steps N] [--torque-limit PCT] [--bin DIR] [--bring-up DIR]\n"
    "      move tests at rising velocity, then acceleration (back and forth inside the\n"
    "      soft limits, recorded every servo cycle as CSV in DIR), stopped at the first\n"
    "      saturation; recommends MAX_VELOCITY, MAX_ACCELERATION, MAX_JERK, FERROR and\n"
    "      MIN_FERROR (the highest clean test less PCT, default 20 %) for write\n"
    "  axis L response [--loop velocity|position] [--step] [--chirp] [--amplitude MM/S|MM]\n"
    "              [--velocity-gain N] [--record DIR] [--bin DIR] --bring-up DIR\n"
    "      step and swept-sine response of the drive's velocity loop (CSV, small\n"
    "      amplitude) where the drive has 0x60F9: rise, overshoot, settling, gain and\n"
    "      phase, -3 dB bandwidth; --velocity-gain writes 0x60F9:1 for the tests (both:\n"
    "      default); the drive's gain and mode are put back afterwards; --loop position:\n"
    "      the position loop instead (CSP, a square or sine of +-MM added to the\n"
    "      position command, default 0.02 mm, at most 0.2)\n"
    "  axis L dial MM [MM2]\n"
    "      the dial indicator's reading of the last test: flips REVERSE, corrects scale\n"
    "      (MM2: a gantry's second side, each side on its own)\n"
    "  axis L switches [--search MM] [--velocity MM/S] [--bin DIR] [--bring-up DIR]\n"
    "      jog towards each end (up to 50 mm, 5 mm/s, time-limited) watching the limit\n"
    "      and home switch inputs: where each changed, its active level\n"
    "  axis L soft-limits [--margin MM]\n"
    "      soft limits = the limit switches found less the margin (2 mm)\n"
    "  homing-methods\n"
    "      the homing methods: the controller's sequence, the CiA 402 drive methods\n"
    "  axis L homing --method controller|drive:N [--repeat N] [--away MM] [--bin DIR]\n"
    "                [--bring-up DIR] [--square MM | --square-pins PIN,PIN]\n"
    "      home N times (5), moving away between runs: reference of each run, spread;\n"
    "      a gantry: each side on its own switch, the racking after homing (entered,\n"
    "      or read from each side's position pin) squared into the second HOME_OFFSET\n"
    "  axis L enable|disable\n"
    "      keep the axis in, or leave it out of, the written configuration\n"
    "  axis L comp-program --out FILE.ngc [--min MM] [--max MM] [--targets N] [--runs N]\n"
    "                      [--overshoot MM] [--dwell S] [--feed MM/MIN] [--seed N]\n"
    "      the ISO 230-2 cycle of the axis (comp/), inside its soft limits; lists its stops\n"
    "  axis L comp-run [--laser-pin PIN | --laser CSV | --camera SOURCE] [--check] [--out FILE.ngc]\n"
    "                  [--pitch MM] [--um-per-px UM] [--scale-at-zero MM] [--scale-sign -1]\n"
    "                  [--frames N] [--bin DIR] [--bring-up DIR]\n"
    "      run the cycle on the controller (time-limited, switched off afterwards); the\n"
    "      position at each stop from HAL pin PIN (a laser's reading, mm), from the\n"
    "      laser's CSV file after the run, or from a camera reading a glass scale\n"
    "      (/dev/videoN, exec:COMMAND a capture program); without one, enter them with\n"
    "      comp-measurements;\n"
    "      --check: a measurement of the compensated machine, kept beside the fit's\n"
    "  axis L comp-measurements (--csv FILE | --values UM,UM,...) [--check]\n"
    "      the measurement from a file (comp/'s measurement CSV or a laser's readings) or\n"
    "      entered deviations (um, one per stop in the cycle's order)\n"
    "  axis L comp-fit [--out-dir DIR] [--install]\n"
    "      fit the error model (comp/), ISO 230-2 figures measured and predicted, the table;\n"
    "      --install: write puts the table and its COMP_FILE keys into the configuration\n"
    "  backup --dir DIR [--interface SPEC] [--ethercat-interface SPEC] [--timeout-ms MS]\n"
    "      SDO upload (CANopen, or CoE on EtherCAT) of the parameters that matter from every\n"
    "      enabled axis's drive, a file per drive (DCF-like); write copies it into\n"
    "      DIR/drive-backup/\n"
    "  restore [--dir DIR | --file FILE ...] [--dry-run] [--interface SPEC]\n"
    "          [--ethercat-interface SPEC] [--timeout-ms MS]\n"
    "      write a backup back (default: the last one taken): checks each drive's identity,\n"
    "      writes the parameters that differ, reads each back; not while a controller\n"
    "      runs; --dry-run lists what would be written\n"
    "  include [--ini FILE] [--hal-before-bus FILE] [--hal-after-bus FILE]\n"
    "      files the written configuration keeps (site I/O, a simulated machine)\n"
    "  bring-up --dir DIR [--name NAME] [--log FILE]\n"
    "      write the configuration of the state (as write --yes) and start cncd on\n"
    "      it in the background, waiting until it answers\n"
    "  shutdown\n"
    "      stop the running controller (cnc shutdown)\n"
    "  write --dir DIR [--name NAME] [--yes] [--cncd PATH]\n"
    "      generate INI and HAL, show the difference; with --yes write them\n"
    "      (old ones kept as .bak) and check them with cncd --check --strict\n"
    "  check [--program FILE] [--timeout S]\n"
    "      start cncd on the configuration write wrote last, E-stop reset, on, home,\n"
    "      run FILE (default: check.ngc beside its INI: every axis to a little inside\n"
    "      its soft limits and back, at reduced feed) to its end, check the end\n"
    "      position, stop cncd; the result is kept in the state. --timeout: at most S s\n"
    "      for the program (default: twice the check program's moves at their feeds and\n"
    "      a minute, at least 600 s; less than its moves take is refused)\n"
    "  wizard [--dir DIR] [--instance NAME]\n"
    "      the Qt wizard over these steps and the same state file\n"
    "      (cnc-commission-wizard)\n"
    "\n"
    "exit status: 0 done, 1 the step found a problem (nothing written), 2 usage\n";

[[noreturn]] void usage(const std::string& why);

// Writes the state's configuration to `dir` and starts cncd on it.
std::unique_ptr<ControllerProcess> bring_up_controller(const State& s, const std::filesystem::path& bin,
                                                       const std::filesystem::path& dir, const std::string& name,
                                                       const std::filesystem::path& log, bool gantry_joints_apart = false) {
  std::filesystem::create_directories(dir);
  WriterOptions o;
  o.gantry_joints_apart = gantry_joints_apart;
  write_config(generate_config(s, dir, name, o));
  std::string out;
  if (check_config(bin / "cncd", dir / (name + ".ini"), out) != 0)
    throw std::runtime_error("the configuration written to " + dir.string() + " does not pass cncd --check --strict:\n" + out);
  return std::make_unique<ControllerProcess>(bin, dir / (name + ".ini"), log);
}

[[noreturn]] void usage(const std::string& why) {
  std::fprintf(stderr, "cnc-commission: %s\n(cnc-commission --help for the commands)\n", why.c_str());
  std::exit(2);
}

struct Args {
  std::vector<std::string> v;
  std::size_t i = 0;
  bool more() const { return i < v.size(); }
  std::string next(const char* what) {
    if (!more()) usage(std::string("missing ") + what);
    return v[i++];
  }
};

double number(const std::string& s, const char* what) {
  try {
    std::size_t n = 0;
    const double d = std::stod(s, &n);
    if (n != s.size()) throw std::invalid_argument(s);
    return d;
  } catch (const std::exception&) {
    usage(std::string(what) + " \"" + s + "\": expected a number");
  }
}

std::filesystem::path self_dir() {
  std::error_code ec;
  const auto p = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::filesystem::path(".") : p.parent_path();
}

int cmd_scan(State& s, Args& a) {
  ScanOptions o;
  std::string spec;
  while (a.more()) {
    const std::string k = a.next("option");
    if (k == "--interface") spec = a.next("interface");
    else if (k == "--bitrate") s.bitrate = static_cast<uint32_t>(number(a.next("bit rate"), "bit rate"));
    // Kept absolute: the written configuration names files in it from
    // another folder, and the state may be used from anywhere.
    else if (k == "--eds-dir") s.eds_dir = std::filesystem::absolute(a.next("folder")).lexically_normal().string();
    else if (k == "--first") o.first = static_cast<int>(number(a.next("node-ID"), "--first"));
    else if (k == "--last") o.last = static_cast<int>(number(a.next("node-ID"), "--last"));
    else if (k == "--timeout-ms") o.timeout_ns = static_cast<int64_t>(number(a.next("ms"), "--timeout-ms") * 1e6);
    else if (k == "--expect") {
      for (const auto& w : cnc::split(a.next("node-IDs"), ','))
        o.expected.push_back(static_cast<int>(number(w, "--expect")));
    } else usage("scan: unknown option " + k);
  }
  if (spec.empty()) spec = s.interface;
  if (spec.empty()) usage("scan: --interface SPEC (e.g. socketcan:can0)");
  o.eds_dir = s.eds_dir;
  auto bus = cnc::can::open_transport(spec);
  const ScanResult r = scan_canopen(*bus, o);
  s.interface = spec;
  s.nodes = r.nodes;
  for (const auto& n : r.nodes) std::cout << describe(n) << "\n";
  for (const auto& p : r.problems) std::cout << "problem: " << p << "\n";
  std::cout << r.nodes.size() << " node(s) on " << spec << (r.ok() ? ", no problems\n" : ", problems above\n");
  s.log.push_back("scan " + spec + ": " + std::to_string(r.nodes.size()) + " node(s)");
  return r.ok() ? 0 : 1;
}

int cmd_lss(State& s, Args& a) {
  LssOptions o;
  std::string spec;
  while (a.more()) {
    const std::string k = a.next("option");
    if (k == "--interface") spec = a.next("interface");
    else if (k == "--first") o.first = static_cast<int>(number(a.next("node-ID"), "--first"));
    else if (k == "--bitrate") o.bitrate = static_cast<uint32_t>(number(a.next("bit rate"), "--bitrate"));
    else if (k == "--window-ms") o.window_ns = static_cast<int64_t>(number(a.next("ms"), "--window-ms") * 1e6);
    else usage("lss: unknown option " + k);
  }
  if (spec.empty()) spec = s.interface;
  if (spec.empty()) usage("lss: --interface SPEC (e.g. socketcan:can0)");
  if (o.first < 1 || o.first > 127) usage("lss: --first must be a node-ID 1-127");
  for (const auto& n : s.nodes) o.taken.insert(n.node_id);
  auto bus = cnc::can::open_transport(spec);
  const LssResult r = assign_node_ids(*bus, o);
  for (const auto& x : r.assigned) std::cout << describe(x) << " (stored)\n";
  for (const auto& p : r.problems) std::cout << "problem: " << p << "\n";
  std::cout << r.assigned.size() << " device(s) given a node-ID on " << spec
            << (r.assigned.empty() ? "" : "; scan again to read them") << "\n";
  s.log.push_back("lss " + spec + ": " + std::to_string(r.assigned.size()) + " device(s) given a node-ID");
  return r.ok() ? 0 : 1;
}

int cmd_scan_ethercat(State& s, Args& a) {
  std::string spec;
  while (a.more()) {
    const std::string k = a.next("option");
    if (k == "--interface") spec = a.next("interface");
    else if (k == "--esi-dir") s.esi_dir = std::filesystem::absolute(a.next("folder")).lexically_normal().string();
    else usage("scan-ethercat: unknown option " + k);
  }
  if (spec.empty()) spec = s.ethercat_interface;
  if (spec.empty()) usage("scan-ethercat: --interface SPEC (e.g. raw:eth0)");
  const EthercatScanResult r = scan_ethercat(spec, s.esi_dir);
  for (const auto& n : r.slaves) std::cout << describe(n) << "\n";
  for (const auto& p : r.problems) std::cout << "problem: " << p << "\n";
  std::cout << r.slaves.size() << " slave(s) on " << spec << (r.ok() ? ", no problems\n" : ", problems above\n");
  s.ethercat_interface = spec;
  s.slaves = r.slaves;
  s.log.push_back("scan-ethercat " + spec + ": " + std::to_string(r.slaves.size()) + " slave(s)");
  return r.ok() ? 0 : 1;
}

void show(const State& s) {
  std::cout << "machine: " << s.machine << "\nbus: " << (s.interface.empty() ? "(not scanned)" : s.interface) << "\n";
  for (const auto& n : s.nodes) std::cout << describe(n) << "\n";
  for (const auto& n : s.slaves) std::cout << describe(n) << "\n";
  for (const auto& a : s.axes) {
    std::cout << "axis " << a.letter << ": joint " << a.joint << ", node " << a.node << (a.enabled ? "" : ", disabled");
    if (a.scaling.counts_per_mm() > 0)
      std::cout << ", " << a.scaling.counts_per_mm() << " counts/mm" << (a.scaling.reverse ? ", REVERSE" : "");
    std::cout << ", limits " << a.min_limit << ".." << a.max_limit << " mm\n";
    if (a.gantry)
      std::cout << "  gantry pair: " << (a.gantry->slave ? "EtherCAT slave " + std::to_string(a.gantry->slave) : "node " + std::to_string(a.gantry->node))
                << " on joint " << a.gantry->joint << (a.gantry->reverse ? ", reversed" : "") << "\n";
    if (a.direction) std::cout << "  direction test: " << a.direction->verdict << "\n";
    if (a.compensation && a.compensation->measured)
      std::cout << "  compensation: measured " << describe(*a.compensation->measured)
                << (a.compensation->fitted ? ", predicted A " + std::to_string(a.compensation->predicted.A) + " um" : "")
                << (a.compensation->install ? ", installed" : "") << "\n";
    if (a.switches)  // steps 5, 6
      std::cout << "  switches: limits " << (a.switches->neg_limit.seen ? std::to_string(a.switches->neg_limit.position) : "-")
                << " / " << (a.switches->pos_limit.seen ? std::to_string(a.switches->pos_limit.position) : "-") << " mm, home "
                << (a.switches->home.seen ? std::to_string(a.switches->home.position) : "-") << " mm\n";
    if (a.homing) std::cout << "  homing: " << a.homing->method << ", spread " << a.homing->spread << " mm\n";
    if (a.tuning)
      std::cout << "  tuning: MAX_VELOCITY " << a.tuning->max_velocity << ", MAX_ACCELERATION " << a.tuning->max_acceleration
                << ", MAX_JERK " << a.tuning->max_jerk << ", FERROR " << a.tuning->ferror << ", MIN_FERROR "
                << a.tuning->min_ferror << " (" << a.tuning->tests.size() << " tests, margin " << a.tuning->margin_pct << " %)\n";
  }
}

// --- Steps 8 (compensation) and 9 (drive-parameter backup), helper C ---
std::filesystem::path g_state_dir = ".";

void print_progress(int done, int total, const std::string& what) {
  std::cout << "progress: " << done << "/" << total << " " << what << std::endl;
}

int cmd_axis_comp(State& s, char letter, const std::string& step, Args& a) {
  Axis* ax = s.axis(letter);
  if (!ax) usage(std::string("axis ") + letter + " has no drive yet");
  const std::string L(1, letter), l(1, static_cast<char>(std::tolower(static_cast<unsigned char>(letter))));
  AxisCompensation c = ax->compensation ? *ax->compensation : default_compensation(*ax);
  if (step == "comp-program") {
    std::filesystem::path out;
    while (a.more()) {
      const std::string k = a.next("option");
      if (k == "--out") out = a.next("file");
      else if (k == "--min") c.x_min = number(a.next("mm"), "--min");
      else if (k == "--max") c.x_max = number(a.next("mm"), "--max");
      else if (k == "--targets") c.targets = static_cast<int>(number(a.next("count"), "--targets"));
      else if (k == "--runs") c.runs = static_cast<int>(number(a.next("count"), "--runs"));
      else if (k == "--overshoot") c.overshoot_mm = number(a.next("mm"), "--overshoot");
      else if (k == "--dwell") c.dwell_s = number(a.next("s"), "--dwell");
      else if (k == "--feed") c.feed_mm_min = number(a.next("mm/min"), "--feed");
      else if (k == "--seed") c.seed = static_cast<uint64_t>(number(a.next("seed"), "--seed"));
      else usage("comp-program: unknown option " + k);
    }
    if (out.empty()) usage("comp-program: --out FILE.ngc");
    check_cycle(*ax, c);
    c.program = std::filesystem::absolute(out).string();
    cnc::write_file_atomically(out, cnc::comp::iso_cycle_gcode(cycle_options(*ax, c)));
    const auto stops = cycle_stops(*ax, c);
    std::cout << describe_stops(letter, stops);
    std::cout << "axis " << L << ": ISO 230-2 cycle " << c.x_min << ".." << c.x_max << " mm, " << stops.size()
              << " stops (" << c.runs << " runs each way), feed " << c.feed_mm_min << " mm/min, written to "
              << out.string() << "\n";
    const bool changed = !ax->compensation || ax->compensation->x_min != c.x_min || ax->compensation->x_max != c.x_max ||
                         ax->compensation->targets != c.targets || ax->compensation->runs != c.runs ||
                         ax->compensation->seed != c.seed;
    if (changed) {  // other stops: the measurement of the old cycle no longer fits them
      c.points.clear();
      c.measured.reset();
    }
    ax->compensation = c;
    s.log.push_back("axis " + L + " comp-program " + out.string());
    return 0;
  }
  if (step == "comp-run") {
    std::filesystem::path laser_csv, out, bin = self_dir(), bring_up;
    std::string pin;
    bool check = false;
    CameraOptions camera;  // --camera: a camera over a glass scale reads each stop
    while (a.more()) {
      const std::string k = a.next("option");
      if (k == "--laser") laser_csv = a.next("file");
      else if (k == "--laser-pin") pin = a.next("HAL pin");
      else if (k == "--camera") camera.source = a.next("camera");
      else if (k == "--pitch") camera.pitch_mm = number(a.next("mm"), "--pitch");
      else if (k == "--um-per-px") camera.um_per_px = number(a.next("um"), "--um-per-px");
      else if (k == "--scale-at-zero") camera.scale_at_zero_mm = number(a.next("mm"), "--scale-at-zero");
      else if (k == "--scale-sign") camera.sign = static_cast<int>(number(a.next("+1 or -1"), "--scale-sign"));
      else if (k == "--frames") camera.frames = static_cast<int>(number(a.next("count"), "--frames"));
      else if (k == "--check") check = true;
      else if (k == "--out") out = a.next("file");
      else if (k == "--bin") bin = a.next("folder");
      else if (k == "--bring-up") bring_up = a.next("folder");
      else usage("comp-run: unknown option " + k);
    }
    if (!laser_csv.empty() + !pin.empty() + !camera.source.empty() > 1)
      usage("comp-run: one of --laser-pin, --laser and --camera");
    if (!(camera.pitch_mm > 0) || !(camera.um_per_px > 0)) usage("comp-run: --pitch and --um-per-px must be > 0");
    if (camera.sign != 1 && camera.sign != -1) usage("comp-run: --scale-sign 1 or -1");
    if (camera.frames < 1 || camera.frames > 100) usage("comp-run: --frames 1 to 100");
    check_cycle(*ax, c);
    if (!out.empty() || c.program.empty()) {
      if (out.empty()) out = g_state_dir / ("comp-" + l + ".ngc");
      c.program = std::filesystem::absolute(out).string();
    }
    cnc::write_file_atomically(c.program, cnc::comp::iso_cycle_gcode(cycle_options(*ax, c)));
    std::unique_ptr<ControllerProcess> own;
    if (!bring_up.empty()) own = bring_up_controller(s, bin, bring_up, "commission", bring_up / "cncd.log");
    const CompRunResult r = camera.source.empty()
                                ? run_comp_cycle(Controller(bin), *ax, c, c.program, pin, print_progress)
                                : run_comp_cycle(Controller(bin), *ax, c, c.program, camera_reader(camera), print_progress,
                                                 /*readings_per_stop=*/1);
    if (own && own->stop() != 0) std::cout << "warning: cncd did not end cleanly (" << (bring_up / "cncd.log").string() << ")\n";
    std::cout << "axis " << L << ": the cycle ran (" << r.stops.size() << " stops); the machine is off again\n";
    ax->compensation = c;
    std::vector<CompPoint> points;
    std::string source;
    if (!pin.empty()) {
      points = points_from_readings(r.stops, r.readings_mm);
      source = "laser pin " + pin;
    } else if (!camera.source.empty()) {
      points = points_from_readings(r.stops, r.readings_mm);
      std::ostringstream src;
      src << "camera " << camera.source << " on a glass scale (pitch " << camera.pitch_mm << " mm, " << camera.um_per_px
          << " um/px)";
      source = src.str();
    } else if (!laser_csv.empty()) {
      points = points_from_readings(r.stops, load_laser_csv(laser_csv, r.stops));
      source = "laser file " + laser_csv.string();
    } else {
      std::cout << describe_stops(letter, r.stops) << "enter the deviation at each stop: cnc-commission axis " << L
                << " comp-measurements --values UM,UM,... (or --csv FILE)\n";
      s.log.push_back("axis " + L + " comp-run (no readings)");
      return 0;
    }
    if (!check && ax->compensation->install)
      std::cout << "note: axis " << L << " had a table installed; this measurement replaces the fit's and drops it. On a "
                   "controller running with the table it measures the compensated machine: use --check for that\n";
    const CompFigures& f = set_measurement(s, letter, points, source, check);
    std::cout << "axis " << L << (check ? " check: " : ": ") << describe(f) << "\n";
    if (check && ax->compensation->fitted)
      std::cout << "axis " << L << ": before compensation A " << ax->compensation->before.A << " um, predicted "
                << ax->compensation->predicted.A << " um, measured now " << f.A << " um\n";
    s.log.push_back("axis " + L + " comp-run" + (check ? " --check" : "") + ": A " + std::to_string(f.A) + " um");
    return 0;
  }
  if (step == "comp-measurements") {
    std::filesystem::path csv;
    std::string values;
    bool check = false;
    while (a.more()) {
      const std::string k = a.next("option");
      if (k == "--csv") csv = a.next("file");
      else if (k == "--values") values = a.next("values");
      else if (k == "--check") check = true;
      else usage("comp-measurements: unknown option " + k);
    }
    if (csv.empty() == values.empty()) usage("comp-measurements: --csv FILE or --values UM,UM,...");
    ax->compensation = c;
    std::vector<CompPoint> points;
    std::string source;
    if (!values.empty()) {
      points = points_from_values(cycle_stops(*ax, c), values);
      source = "entered";
    } else {
      const std::string text = cnc::read_file(csv);
      if (text.find("deviation_um") != std::string::npos) {
        points = points_from_measurement_file(*ax, csv);
        source = "measurement file " + csv.string();
      } else {
        points = points_from_readings(cycle_stops(*ax, c), load_laser_csv(csv, cycle_stops(*ax, c)));
        source = "laser file " + csv.string();
      }
    }
    if (!check && ax->compensation->install)
      std::cout << "note: axis " << L << " had a table installed; this measurement replaces the fit's and drops it "
                   "(--check keeps a measurement of the compensated machine beside it)\n";
    const CompFigures& f = set_measurement(s, letter, points, source, check);
    std::cout << "axis " << L << (check ? " check: " : ": ") << points.size() << " points, " << describe(f) << "\n";
    s.log.push_back("axis " + L + " comp-measurements (" + source + ")");
    return 0;
  }
  if (step == "comp-fit") {
    std::filesystem::path dir = g_state_dir / ("comp-" + l);
    bool install = false;
    while (a.more()) {
      const std::string k = a.next("option");
      if (k == "--out-dir") dir = a.next("folder");
      else if (k == "--install") install = true;
      else usage("comp-fit: unknown option " + k);
    }
    std::cout << fit_compensation(s, letter, dir, install);
    const AxisCompensation& r = *ax->compensation;
    std::cout << "axis " << L << ": ISO 230-2 A " << r.before.A << " um measured, " << r.predicted.A
              << " um predicted with the table (" << r.nominal.size() << " entries); files in " << r.fit_dir << "\n"
              << (install ? "the table is marked for the configuration: cnc-commission write puts it in\n"
                          : "(--install marks the table for cnc-commission write)\n");
    s.log.push_back("axis " + L + " comp-fit" + (install ? " --install" : ""));
    return 0;
  }
  usage("axis: unknown step " + step);
}

int cmd_backup(State& s, Args& a) {
  std::filesystem::path dir;
  std::string spec = s.interface, ecat = s.ethercat_interface;
  BackupOptions o;
  while (a.more()) {
    const std::string k = a.next("option");
    if (k == "--dir") dir = a.next("folder");
    else if (k == "--interface") spec = a.next("interface");
    else if (k == "--ethercat-interface") ecat = a.next("interface");
    else if (k == "--timeout-ms") o.timeout_ns = static_cast<int64_t>(number(a.next("ms"), "--timeout-ms") * 1e6);
    else usage("backup: unknown option " + k);
  }
  if (dir.empty()) usage("backup: --dir DIR");
  if (s.axes.empty()) throw std::invalid_argument("backup: no axis has a drive yet: assign them first");
  const bool on_can = has_canopen_axes(s), on_ecat = has_ethercat_axes(s);
  if (on_can && spec.empty()) usage("backup: no CAN bus: scan first, or --interface SPEC");
  if (on_ecat && ecat.empty()) usage("backup: no EtherCAT segment: scan-ethercat first, or --ethercat-interface SPEC");
  BackupResult r;
  if (on_can || !on_ecat) {
    if (spec.empty()) usage("backup: no bus: scan first, or --interface SPEC");
    auto bus = cnc::can::open_transport(spec);
    r = backup_drives(*bus, s, o);
  }
  if (on_ecat) {
    BackupResult e = backup_ethercat_drives(ecat, s);
    r.nodes.insert(r.nodes.end(), e.nodes.begin(), e.nodes.end());
    r.skipped.insert(r.skipped.end(), e.skipped.begin(), e.skipped.end());
    r.problems.insert(r.problems.end(), e.problems.begin(), e.problems.end());
  }
  for (const auto& k : r.skipped) std::cout << k << "\n";
  for (const auto& n : r.nodes) {
    std::cout << (n.slave ? "EtherCAT slave " + std::to_string(n.slave) : "node " + std::to_string(n.node)) << " (axis "
              << n.axis << "): " << n.values.size() << " values, " << n.missing.size()
              << " object(s) the drive lacks\n";
    for (const auto& m : n.missing) std::cout << "  missing: " << m << "\n";
  }
  if (!r.ok()) {
    for (const auto& p : r.problems) std::cout << "problem: " << p << "\n";
    return 1;
  }
  if (on_ecat) s.ethercat_interface = ecat;
  for (const auto& f : write_backup(s, r, dir)) std::cout << "wrote " << f.string() << "\n";
  s.log.push_back("backup of " + std::to_string(r.nodes.size()) + " drive(s) to " + dir.string());
  return 0;
}
// --- end of helper C's block ---

// --- Drive-parameter restore (issue 21) ---
// A controller running on this instance (its segment and process alive):
// "" when none.
std::string running_controller() {
  try {
    const cnc::ipc::Client c;
    if (c.controller_alive())
      return "a controller (cncd, pid " + std::to_string(c.owner_pid()) + ", instance " + c.instance() + ")";
  } catch (const std::exception&) {
  }
  return "";
}

int cmd_restore(State& s, Args& a) {
  std::vector<std::filesystem::path> files;
  std::filesystem::path dir;
  std::string spec = s.interface, ecat = s.ethercat_interface;
  bool dry_run = false;
  RestoreBuses buses;
  while (a.more()) {
    const std::string k = a.next("option");
    if (k == "--dir") dir = a.next("folder");
    else if (k == "--file") files.push_back(a.next("file"));
    else if (k == "--interface") spec = a.next("interface");
    else if (k == "--ethercat-interface") ecat = a.next("interface");
    else if (k == "--dry-run") dry_run = true;
    else if (k == "--timeout-ms") buses.sdo_timeout_ns = static_cast<int64_t>(number(a.next("ms"), "--timeout-ms") * 1e6);
    else usage("restore: unknown option " + k);
  }
  if (!dir.empty() && !files.empty()) usage("restore: --dir DIR or --file FILE, not both");
  if (dir.empty() && files.empty()) {
    if (!s.backup) usage("restore: --dir DIR or --file FILE (no backup taken yet in this state)");
    dir = s.backup->dir;
  }
  // The drives' parameters change under a controller that runs them: it
  // would go on with the old ones (or fault), and the EtherCAT mailbox
  // would be shared by two masters.
  if (const std::string c = running_controller(); !c.empty()) {
    std::cout << "problem: " << c << " runs the machine: restore does not change drive parameters under it; stop it "
              << "first (cnc-commission shutdown), then restore; nothing was written\n";
    return 1;
  }
  std::vector<BackupFile> backups;
  try {
    if (!dir.empty()) backups = load_backup_dir(dir);
    for (const auto& f : files) backups.push_back(load_backup_file(f));
  } catch (const std::exception& e) {
    std::cout << "problem: " << e.what() << "; nothing was written\n";
    return 1;
  }
  const bool on_can = std::any_of(backups.begin(), backups.end(), [](const BackupFile& f) { return f.slave == 0; });
  const bool on_ecat = std::any_of(backups.begin(), backups.end(), [](const BackupFile& f) { return f.slave != 0; });
  std::unique_ptr<cnc::can::Transport> bus;
  std::unique_ptr<cnc::ethercat::Master> master;
  if (on_can && !spec.empty()) {
    bus = cnc::can::open_transport(spec);
    buses.can = bus.get();
  }
  if (on_ecat && !ecat.empty()) {
    cnc::ethercat::MasterConfig cfg;
    cfg.interface = ecat;
    try {
      master = std::make_unique<cnc::ethercat::Master>(cfg, nullptr);
      master->to_preop();
      buses.ethercat = master.get();
    } catch (const std::exception& e) {
      std::cout << "problem: " << ecat << ": " << e.what() << "; nothing was written\n";
      return 1;
    }
  }
  const RestoreResult r = restore_drives(backups, buses, dry_run);
  if (master) master->release();
  std::cout << describe(r);
  if (!r.ok()) {
    std::cout << (dry_run ? "dry run: problems above\n" : "restore: problems above\n");
    return 1;
  }
  std::size_t written = 0;
  for (const auto& d : r.drives)
    for (const auto& k : d.changes) written += k.written ? 1 : 0;
  if (dry_run) {
    std::cout << "dry run: nothing written\n";
    return 0;
  }
  std::cout << "restored " << written << " parameter(s) to " << r.drives.size() << " drive(s)\n";
  s.log.push_back("restore of " + std::to_string(r.drives.size()) + " drive(s) from " +
                  (dir.empty() ? files.front().parent_path().string() : dir.string()) + ": " + std::to_string(written) +
                  " parameter(s) written");
  return 0;
}
// --- end of the restore block ---

// --- Steps 5 and 6 (helper A): switches, soft limits from them, homing. ---
std::string fmt_mm(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3f", v);
  return b;
}

std::string describe_switch(const char* name, const SwitchFinding& f) {
  if (!f.seen) return std::string(name) + ": not seen (" + f.pin + ")";
  std::string t = std::string(name) + ": at " + fmt_mm(f.position) + " mm";
  if (f.has_high) t += " to " + fmt_mm(f.position_high) + " mm";
  return t + ", active " + (f.active_high ? "high" : "low") + " (" + f.pin + ")";
}

int axis_steps56(State& s, Args& a, char letter, const std::string& step) {
  Axis* ax = s.axis(letter);
  if (!ax) usage(std::string("axis ") + letter + " has no drive yet");
  const std::string L(1, letter);
  std::filesystem::path bin = self_dir(), bring_up;
  if (step == "soft-limits") {
    double margin = 2;
    while (a.more()) {
      const std::string k = a.next("option");
      if (k == "--margin") margin = number(a.next("mm"), "--margin");
      else usage("soft-limits: unknown option " + k);
    }
    soft_limits_from_switches(*ax, margin);
    std::cout << "axis " << letter << ": soft limits " << fmt_mm(ax->min_limit) << " .. " << fmt_mm(ax->max_limit)
              << " mm (limit switches less " << fmt_mm(margin) << " mm)\n";
    s.log.push_back("axis " + L + " soft limits from the switches");
    return 0;
  }
  if (step == "switches") {
    double search = 50, velocity = 5;
    while (a.more()) {
      const std::string k = a.next("option");
      if (k == "--search") search = number(a.next("mm"), "--search");
      else if (k == "--velocity") velocity = number(a.next("mm/s"), "--velocity");
      else if (k == "--bin") bin = a.next("folder");
      else if (k == "--bring-up") bring_up = a.next("folder");
      else usage("switches: unknown option " + k);
    }
    if (!(search > 0) || !(velocity > 0)) usage("switches: --search and --velocity must be > 0");
    std::unique_ptr<ControllerProcess> own;
    if (!bring_up.empty()) own = bring_up_controller(s, bin, bring_up, "commission", bring_up / "cncd.log", true);
    std::vector<AxisSwitches> found;  // a gantry pair: each joint's own switches
    std::string all;
    for (const Axis& j : step_joints(*ax)) {
      const AxisSwitches r = find_switches(Controller(bin), j, search, velocity, stdout);
      std::cout << "axis " << letter << (found.empty() ? "" : " (gantry joint " + std::to_string(j.joint) + ")")
                << ": searched " << fmt_mm(search) << " mm each way from " << fmt_mm(r.start)
                << " mm at " << fmt_mm(r.velocity) << " mm/s; the machine is off again\n"
                << "  " << describe_switch("negative limit", r.neg_limit) << "\n  "
                << describe_switch("positive limit", r.pos_limit) << "\n  " << describe_switch("home switch", r.home) << "\n";
      for (const auto& p : r.problems) all += (all.empty() ? "" : "\n") + p;
      found.push_back(r);
    }
    if (own && own->stop() != 0) std::cout << "warning: cncd did not end cleanly (" << (bring_up / "cncd.log").string() << ")\n";
    if (!all.empty()) throw std::runtime_error(all + "\n(nothing saved)");
    ax->switches = found.front();
    if (ax->gantry) ax->gantry->switches = found.back();
    s.log.push_back("axis " + L + " switches found");
    return 0;
  }
  // homing
  std::string method;
  int repeat = 5;
  double away = 5, square = 0;  // a gantry: the second side's measured lead after homing (mm)
  std::vector<std::string> square_pins;
  while (a.more()) {
    const std::string k = a.next("option");
    if (k == "--method") method = a.next("method");
    else if (k == "--repeat") repeat = static_cast<int>(number(a.next("count"), "--repeat"));
    else if (k == "--away") away = number(a.next("mm"), "--away");
    else if (k == "--square") square = number(a.next("mm"), "--square");
    else if (k == "--square-pins") square_pins = cnc::split(a.next("PIN,PIN"), ',');
    else if (k == "--bin") bin = a.next("folder");
    else if (k == "--bring-up") bring_up = a.next("folder");
    else usage("homing: unknown option " + k);
  }
  if (method.empty()) usage("homing: --method controller|drive:N (cnc-commission homing-methods)");
  if (repeat < 1 || repeat > 100) usage("homing: --repeat 1..100");
  if (!(away > 0)) usage("homing: --away must be > 0");
  if (!square_pins.empty() && (square_pins.size() != 2 || !ax->gantry))
    usage("homing: --square-pins FIRST,SECOND (two HAL pins, each side's position) on a gantry pair");
  if (square != 0 && !ax->gantry) usage("homing: --square is for a gantry pair");
  Axis planned = *ax;
  planned.homing = plan_homing(*ax, method);
  if (ax->gantry) {  // each side on its own switch, one synchronised group
    planned.gantry->homing = plan_gantry_homing(*ax, *planned.homing, method, square);
    planned.gantry->squaring = square;
  }
  std::unique_ptr<ControllerProcess> own;
  if (!bring_up.empty()) {
    State with = s;
    *with.axis(letter) = planned;
    own = bring_up_controller(with, bin, bring_up, "commission", bring_up / "cncd.log");
  }
  for (const Axis& j : step_joints(planned)) {
    const std::vector<double> refs = run_homing(Controller(bin), j, repeat, away, stdout);
    AxisHoming& h = j.joint == planned.joint ? *planned.homing : *planned.gantry->homing;
    h.references = refs;
    h.spread = spread(refs);
    std::cout << "axis " << letter << (j.joint == planned.joint ? "" : " (gantry joint " + std::to_string(j.joint) + ")")
              << ": " << method << ", " << refs.size() << " runs, spread " << fmt_mm(h.spread * 1000) << " um ("
              << h.measured << ")\n";
  }
  if (!square_pins.empty()) {  // the squaring: the racking left by the switch edges, folded into HOME_OFFSET
    const double d = measure_racking(Controller(bin), planned, square_pins[0], square_pins[1]);
    planned.gantry->homing->home_offset += d;
    planned.gantry->squaring += d;
    std::cout << "axis " << letter << ": homed, the second side stood " << fmt_mm(d) << " mm ahead of the first ("
              << square_pins[1] << " - " << square_pins[0] << "): its HOME_OFFSET is now "
              << fmt_mm(planned.gantry->homing->home_offset) << " mm (squaring " << fmt_mm(planned.gantry->squaring)
              << " mm)\n";
  }
  if (own && own->stop() != 0) std::cout << "warning: cncd did not end cleanly (" << (bring_up / "cncd.log").string() << ")\n";
  *ax = planned;
  s.log.push_back("axis " + L + " homing " + method);
  return 0;
}
// --- end of steps 5 and 6 ---

// --- step 7, tuning (helper B) ---
std::filesystem::path g_state_file = "commission.json";

int cmd_tune(State& s, Args& a, char letter) {
  TuneOptions o;
  bool torque_given = false;
  std::filesystem::path bin = self_dir(), bring_up;
  while (a.more()) {
    const std::string k = a.next("option");
    if (k == "--max-velocity") o.max_velocity = number(a.next("mm/s"), "--max-velocity");
    else if (k == "--max-acceleration") o.max_acceleration = number(a.next("mm/s2"), "--max-acceleration");
    else if (k == "--margin") o.margin_pct = number(a.next("percent"), "--margin");
    else if (k == "--record") o.record_dir = a.next("folder");
    else if (k == "--steps") o.steps = static_cast<int>(number(a.next("count"), "--steps"));
    else if (k == "--torque-limit") {
      o.rule.torque_limit_pct = number(a.next("percent"), "--torque-limit");
      torque_given = true;
    }
    else if (k == "--bin") bin = a.next("folder");
    else if (k == "--bring-up") bring_up = a.next("folder");
    else usage("tune: unknown option " + k);
  }
  Axis* ax = s.axis(letter);
  if (!ax) usage(std::string("axis ") + letter + " has no drive yet");
  if (!(o.max_velocity > 0) || !(o.max_acceleration > 0)) usage("tune: --max-velocity and --max-acceleration must be > 0");
  if (!(o.margin_pct >= 10 && o.margin_pct < 90)) usage("tune: --margin PCT: 10 to 90");
  if (o.steps < 2 || o.steps > 20) usage("tune: --steps N: 2 to 20");
  if (!(o.rule.torque_limit_pct > 0)) usage("tune: --torque-limit PCT must be > 0");
  if (o.record_dir.empty())
    o.record_dir = g_state_file.parent_path() / ("tuning-" + std::string(1, static_cast<char>(std::tolower(letter))));
  o.progress = [](const std::string& l) { std::cout << "progress: " << l << std::endl; };
  o.report = [](const std::string& l) { std::cout << l << std::endl; };
  std::unique_ptr<ControllerProcess> own;
  if (!torque_given)  // the drive's own limit (0x6072) as the scan read it
    if (const auto pct = drive_max_torque_pct(s, *ax)) o.rule.torque_limit_pct = *pct;
  if (!bring_up.empty())
    // A gantry pair homes together and is tuned as one axis; other axes
    // are tuned in joint mode, unhomed.
    own = bring_up_controller(tuning_configuration(s, letter, o), bin, bring_up, "commission-tune", bring_up / "cncd.log",
                              !ax->gantry);
  const AxisTuning t = run_tuning(Controller(bin), *ax, o);
  if (own && own->stop() != 0) std::cout << "warning: cncd did not end cleanly (" << (bring_up / "cncd.log").string() << ")\n";
  std::cout << "axis " << letter << ": the machine is off again\n"
            << "velocity: " << t.velocity_limit << "\nacceleration: " << t.acceleration_limit << "\n"
            << "recommended (margin " << t.margin_pct << " %): MAX_VELOCITY = " << t.max_velocity
            << ", MAX_ACCELERATION = " << t.max_acceleration << ", MAX_JERK = " << t.max_jerk
            << ", FERROR = " << t.ferror << ", MIN_FERROR = " << t.min_ferror << "\n";
  ax->tuning = t;
  s.log.push_back("axis " + std::string(1, letter) + " tuned");
  return 0;
}

// Step 7's loop response (commission/response.hpp): on a controller of its
// own (the response configuration), the drive's gains read by SDO (CoE
// SDO on EtherCAT) first.
int cmd_response(State& s, Args& a, char letter) {
  ResponseOptions o;
  std::filesystem::path bin = self_dir(), bring_up;
  std::optional<uint32_t> gain;
  std::optional<double> amplitude;  // mm/s on the velocity loop, mm on the position loop
  bool step = false, chirp = false;
  while (a.more()) {
    const std::string k = a.next("option");
    if (k == "--step") step = true;
    else if (k == "--chirp") chirp = true;
    else if (k == "--loop") {
      const std::string l = a.next("velocity|position");
      if (l == "velocity") o.loop = Loop::Velocity;
      else if (l == "position") o.loop = Loop::Position;
      else usage("response: --loop velocity|position, not " + l);
    } else if (k == "--amplitude") amplitude = number(a.next("mm/s or mm"), "--amplitude");
    else if (k == "--velocity-gain") gain = static_cast<uint32_t>(number(a.next("gain"), "--velocity-gain"));
    else if (k == "--record") o.record_dir = a.next("folder");
    else if (k == "--bin") bin = a.next("folder");
    else if (k == "--bring-up") bring_up = a.next("folder");
    else usage("response: unknown option " + k);
  }
  Axis* ax = s.axis(letter);
  if (!ax) usage(std::string("axis ") + letter + " has no drive yet");
  if (o.loop == Loop::Velocity && amplitude) o.amplitude_mm_s = *amplitude;
  if (o.loop == Loop::Position && amplitude) o.amplitude_mm = *amplitude;
  if (!(o.amplitude_mm_s > 0 && o.amplitude_mm_s <= kMaxResponseAmplitude)) usage("response: --amplitude MM/S: 0 to 20");
  if (!(o.amplitude_mm > 0 && o.amplitude_mm <= kMaxPositionResponseAmplitude))
    usage("response --loop position: --amplitude MM: 0 to 0.2");
  if (gain && *gain == 0) usage("response: --velocity-gain must be > 0");
  if (bring_up.empty()) usage("response: --bring-up DIR (the test runs on a response configuration of its own)");
  if (step || chirp) {  // one named: only it; neither: both
    o.step = step;
    o.chirp = chirp;
  }
  if (o.record_dir.empty())
    o.record_dir = g_state_file.parent_path() / ("response-" + std::string(1, static_cast<char>(std::tolower(letter))));
  o.progress = [](const std::string& l) { std::cout << "progress: " << l << std::endl; };
  o.report = [](const std::string& l) { std::cout << l << std::endl; };
  std::filesystem::create_directories(bring_up);
  write_config(response_configuration(s, letter, bring_up, "commission-response"));
  std::string out;
  if (check_config(bin / "cncd", bring_up / "commission-response.ini", out) != 0)
    throw std::runtime_error("the configuration written to " + bring_up.string() + " does not pass cncd --check --strict:\n" + out);
  // The gains (--velocity-gain written first): EtherCAT before cncd
  // starts, CANopen while it runs (response_gains). What the response
  // changed in the drive goes back whatever happens (done, an error,
  // Ctrl-C): EtherCAT once cncd stopped, CANopen while it still runs.
  AxisResponse r;
  DriveFound found;
  const bool before = response_gains_before_controller(*ax);
  auto gains = [&] {
    const auto g = response_gains(s, *ax, gain, r.skipped, found);
    if (g) {
      r.gains = *g;
      if (found.velocity_gain) std::cout << "axis " << letter << ": wrote " << *gain << " to 0x60F9:01\n";
    }
  };
  auto put_back = [&]() -> std::string {  // "" when done, else why not
    try {
      restore_drive(s, *ax, found);
    } catch (const std::exception& e) {
      return std::string("; ") + e.what() + ": the drive keeps what the response left";
    }
    if (found.velocity_gain)
      std::cout << "axis " << letter << ": put back the velocity gain " << *found.velocity_gain << " (0x60F9:01)\n";
    return {};
  };
  std::string not_put_back;
  try {
    if (before) gains();
    ControllerProcess own(bin, bring_up / "commission-response.ini", bring_up / "cncd.log");
    try {
      if (!before) {
        wait_node_operational(Controller(bin), *ax);
        gains();
      }
      if (!r.skipped.empty()) {
        std::cout << "axis " << letter << ": no loop response measured: " << r.skipped << "\n";
      } else {
        std::cout << "axis " << letter << ": velocity gain 0x60F9:01 = " << r.gains.velocity_gain
                  << " (0.1 mN m s/rad on the simulated drive), integration time 0x60F9:02 = " << r.gains.velocity_integral;
        if (r.gains.position_gain) std::cout << ", position gain 0x60FB:01 = " << *r.gains.position_gain;
        std::cout << "\n";
        const AxisResponse m = run_response(Controller(bin), *ax, o);
        r.step = m.step;
        r.chirp = m.chirp;
        r.position_step = m.position_step;
        r.position_chirp = m.position_chirp;
      }
    } catch (const std::exception&) {
      if (!before) not_put_back = put_back();
      throw;
    }
    if (!before) not_put_back = put_back();
    if (own.stop() != 0) std::cout << "warning: cncd did not end cleanly (" << (bring_up / "cncd.log").string() << ")\n";
  } catch (const std::exception& e) {
    if (before) not_put_back = put_back();
    throw std::runtime_error(e.what() + not_put_back);
  }
  if (before) not_put_back = put_back();
  if (!not_put_back.empty()) throw std::runtime_error("axis " + std::string(1, letter) + ": measured" + not_put_back);
  std::cout << "axis " << letter << ": the machine is off again\n";
  // The other loop's figures stay when they were measured at the same
  // gains (a response of the velocity loop and one of the position loop).
  const auto& old = ax->response;
  if (old && r.skipped.empty() && old->skipped.empty() && old->gains.velocity_gain == r.gains.velocity_gain &&
      old->gains.velocity_integral == r.gains.velocity_integral && old->gains.position_gain == r.gains.position_gain) {
    if (o.loop == Loop::Position) {
      r.step = old->step;
      r.chirp = old->chirp;
    } else {
      r.position_step = old->position_step;
      r.position_chirp = old->position_chirp;
    }
  }
  ax->response = r;
  s.log.push_back("axis " + std::string(1, letter) + (r.skipped.empty() ? " loop response measured" : " loop response skipped"));
  return 0;
}
// --- end of step 7 ---

int cmd_axis(State& s, Args& a) {
  const std::string l = a.next("axis letter");
  if (l.size() != 1) usage("axis \"" + l + "\": expected one letter");
  const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(l[0])));
  const std::string step = a.next("axis step");
  if (step == "assign") {
    int node = -1, joint = -1, slave = -1;
    // A gantry pair: the second drive (--gantry-node or --gantry-slave),
    // its joint (default the next free one) and direction.
    int gantry_node = -1, gantry_slave = -1, gantry_joint = -1;
    bool gantry_reverse = false;
    while (a.more()) {
      const std::string k = a.next("option");
      if (k == "--node") node = static_cast<int>(number(a.next("node-ID"), "--node"));
      else if (k == "--slave") slave = static_cast<int>(number(a.next("slave position"), "--slave"));
      else if (k == "--joint") joint = static_cast<int>(number(a.next("joint"), "--joint"));
      else if (k == "--gantry-node") gantry_node = static_cast<int>(number(a.next("node-ID"), "--gantry-node"));
      else if (k == "--gantry-slave") gantry_slave = static_cast<int>(number(a.next("slave position"), "--gantry-slave"));
      else if (k == "--gantry-joint") gantry_joint = static_cast<int>(number(a.next("joint"), "--gantry-joint"));
      else if (k == "--gantry-reverse") gantry_reverse = true;
      else usage("assign: unknown option " + k);
    }
    if ((node < 0) == (slave < 0)) usage("assign: --node ID (CANopen) or --slave POSITION (EtherCAT)");
    if (gantry_node >= 0 && node < 0) usage("assign: --gantry-node goes with --node (one bus for both drives)");
    if (gantry_slave >= 0 && slave < 0) usage("assign: --gantry-slave goes with --slave (one bus for both drives)");
    if ((gantry_joint >= 0 || gantry_reverse) && gantry_node < 0 && gantry_slave < 0)
      usage("assign: --gantry-joint and --gantry-reverse need --gantry-node or --gantry-slave");
    // Joints in use by the other axes and their gantry drives.
    std::vector<int> taken;
    for (const MachineJoint& mj : machine_joints(s))
      if (mj.axis.letter != letter) taken.push_back(mj.axis.joint);
    const auto next_free = [&taken](int from) {
      while (std::find(taken.begin(), taken.end(), from) != taken.end()) ++from;
      return from;
    };
    if (joint < 0) joint = s.axis(letter) ? s.axis(letter)->joint : next_free(0);
    std::optional<GantryDrive> gantry;
    if (gantry_node >= 0 || gantry_slave >= 0) {
      taken.push_back(joint);
      gantry = GantryDrive{std::max(gantry_node, 0), std::max(gantry_slave, 0),
                           gantry_joint >= 0 ? gantry_joint : next_free(joint + 1), gantry_reverse};
    }
    const auto say_gantry = [&gantry](const Axis& ax) {
      if (!gantry) return std::string();
      return ", gantry pair with " +
             (ax.gantry->slave ? "EtherCAT slave " + std::to_string(ax.gantry->slave) : "node " + std::to_string(ax.gantry->node)) +
             " on joint " + std::to_string(ax.gantry->joint) + (ax.gantry->reverse ? " (reversed)" : "");
    };
    if (slave >= 0) {
      const Axis& ax = assign_axis_ethercat(s, letter, joint, slave, gantry);
      std::cout << "axis " << letter << ": EtherCAT slave " << ax.slave << " on joint " << ax.joint << say_gantry(ax) << "\n";
      s.log.push_back("axis " + std::string(1, letter) + " assigned to EtherCAT slave " + std::to_string(slave));
      return 0;
    }
    const Axis& ax = assign_axis(s, letter, joint, node, gantry);
    std::cout << "axis " << letter << ": node " << ax.node << " on joint " << ax.joint << say_gantry(ax) << "\n";
    s.log.push_back("axis " + std::string(1, letter) + " assigned to node " + std::to_string(node));
  } else if (step == "scaling") {
    double lead = 0, counts = 0, gm = 0, gl = 0;
    while (a.more()) {
      const std::string k = a.next("option");
      if (k == "--lead") lead = number(a.next("lead"), "--lead");
      else if (k == "--counts") counts = number(a.next("counts"), "--counts");
      else if (k == "--gear") {
        const auto w = cnc::split(a.next("gear"), ':');
        if (w.size() != 2) usage("--gear MOTOR:LOAD, e.g. 3:1");
        gm = number(w[0], "--gear");
        gl = number(w[1], "--gear");
      } else usage("scaling: unknown option " + k);
    }
    const double cpm = set_scaling(s, letter, lead, counts, gm, gl);
    std::cout << "axis " << letter << ": " << cpm << " counts/mm (" << s.axis(letter)->scaling.source << ")\n";
    s.log.push_back("axis " + std::string(1, letter) + " scaling");
  } else if (step == "limits") {
    Axis* ax = s.axis(letter);
    if (!ax) usage(std::string("axis ") + letter + " has no drive yet");
    bool given_limits = false;
    while (a.more()) {
      const std::string k = a.next("option");
      if (k == "--min") {
        ax->min_limit = number(a.next("mm"), "--min");
        given_limits = true;
      } else if (k == "--max") {
        ax->max_limit = number(a.next("mm"), "--max");
        given_limits = true;
      }
      else if (k == "--velocity") ax->max_velocity = number(a.next("mm/s"), "--velocity");
      else if (k == "--acceleration") ax->max_acceleration = number(a.next("mm/s2"), "--acceleration");
      else usage("limits: unknown option " + k);
    }
    if (!(ax->min_limit < ax->max_limit)) throw std::invalid_argument(std::string("axis ") + letter + ": --min must be below --max");
    if (given_limits) ax->limits_source = "entered";  // the person knows this travel
    if (!(ax->max_velocity > 0) || !(ax->max_acceleration > 0))
      throw std::invalid_argument(std::string("axis ") + letter + ": velocity and acceleration must be > 0");
  } else if (step == "direction-test") {
    double distance = 5, velocity = 2, dial = 0, dial2 = 0;
    bool has_dial = false, has_dial2 = false;  // dial2: a gantry's second side
    bool hold = false;
    std::filesystem::path bin = self_dir(), bring_up;
    while (a.more()) {
      const std::string k = a.next("option");
      if (k == "--distance") distance = number(a.next("mm"), "--distance");
      else if (k == "--velocity") velocity = number(a.next("mm/s"), "--velocity");
      else if (k == "--dial") {
        dial = number(a.next("mm"), "--dial");
        has_dial = true;
      } else if (k == "--dial2") {
        dial2 = number(a.next("mm"), "--dial2");
        has_dial2 = true;
      } else if (k == "--hold") hold = true;
      else if (k == "--bin") bin = a.next("folder");
      else if (k == "--bring-up") bring_up = a.next("folder");
      else usage("direction-test: unknown option " + k);
    }
    Axis* ax = s.axis(letter);
    if (!ax) usage(std::string("axis ") + letter + " has no drive yet");
    std::unique_ptr<ControllerProcess> own;
    if (has_dial2 && !ax->gantry) usage("direction-test: --dial2 is the second side of a gantry pair");
    if (!bring_up.empty()) own = bring_up_controller(s, bin, bring_up, "commission", bring_up / "cncd.log", true);
    std::optional<HoldToRun> held;
    if (hold) {
      std::cout << "axis " << letter << ": hold a key (the space bar) to jog; let it go to stop" << std::endl;
      held.emplace(STDIN_FILENO, kHoldFirstKeyNs);
    }
    const JogResult r = direction_jog(Controller(bin), *ax, distance, velocity);
    held.reset();
    if (r.limited)
      std::cout << "axis " << letter << ": jogged " << r.commanded_mm << " mm, not " << distance << ": "
                << (ax->scaling.dial_checked ? "a direction test jogs at most " + std::to_string(static_cast<int>(kMaxTestTravel)) + " mm"
                                             : "no dial reading has checked the scaling yet, and until one has the table may "
                                               "move a multiple of the command (enter the dial reading, then test farther)")
                << "\n";
    if (own && own->stop() != 0) std::cout << "warning: cncd did not end cleanly (" << (bring_up / "cncd.log").string() << ")\n";
    std::cout << "axis " << letter << ": commanded " << r.commanded_mm << " mm, drive feedback " << r.feedback_mm
              << " mm; the machine is off again\n";
    std::cout << apply_direction_test(s, letter, r.commanded_mm, r.feedback_mm, dial, has_dial).verdict << "\n";
    if (r.gantry_feedback_mm)  // the gantry's second drive, jogged with the first
      std::cout << apply_direction_test(s, letter, r.commanded_mm, *r.gantry_feedback_mm, dial2, has_dial2, true).verdict << "\n";
    s.log.push_back("axis " + std::string(1, letter) + " direction test");
  } else if (step == "tune") {
    return cmd_tune(s, a, letter);
  } else if (step == "response") {
    return cmd_response(s, a, letter);
  } else if (step == "dial") {
    const double dial = number(a.next("dial reading (mm)"), "dial");
    const Axis* ax = s.axis(letter);
    if (!ax || !ax->direction) usage(std::string("axis ") + letter + ": no direction test to go with the dial reading");
    const DirectionTest t = *ax->direction;
    std::optional<double> dial2;  // a gantry pair: the second side's reading
    if (a.more()) dial2 = number(a.next("second dial reading (mm)"), "dial");
    if (dial2 && (!ax->gantry || !ax->gantry->direction))
      usage(std::string("axis ") + letter + ": a second dial reading is for a gantry pair's second drive after its direction test");
    const std::optional<DirectionTest> t2 = ax->gantry ? ax->gantry->direction : std::nullopt;
    std::cout << apply_direction_test(s, letter, t.commanded_mm, t.feedback_mm, dial, true).verdict << "\n";
    if (dial2) std::cout << apply_direction_test(s, letter, t2->commanded_mm, t2->feedback_mm, *dial2, true, true).verdict << "\n";
    s.log.push_back("axis " + std::string(1, letter) + " dial " + l);
  } else if (step.rfind("comp-", 0) == 0) {
    return cmd_axis_comp(s, letter, step, a);  // step 8
  } else if (step == "switches" || step == "soft-limits" || step == "homing") {  // steps 5, 6
    return axis_steps56(s, a, letter, step);
  } else if (step == "enable" || step == "disable") {
    Axis* ax = s.axis(letter);
    if (!ax) usage(std::string("axis ") + letter + " has no drive yet");
    ax->enabled = step == "enable";
  } else {
    usage("axis: unknown step " + step);
  }
  return 0;
}

int cmd_bring_up(State& s, Args& a) {
  std::filesystem::path dir, log;
  std::string name = "commission";
  while (a.more()) {
    const std::string k = a.next("option");
    if (k == "--dir") dir = a.next("folder");
    else if (k == "--name") name = a.next("name");
    else if (k == "--log") log = a.next("file");
    else usage("bring-up: unknown option " + k);
  }
  if (dir.empty()) usage("bring-up: --dir DIR");
  if (log.empty()) log = dir / "cncd.log";
  // A gantry pair whose sides are not both homing-commissioned yet: its
  // joints apart, so the steps may jog each before homing.
  const bool apart = std::any_of(s.axes.begin(), s.axes.end(), [](const Axis& x) {
    return x.gantry && (!x.homing || !x.gantry->homing);
  });
  auto c = bring_up_controller(s, self_dir(), dir, name, log, apart);
  std::cout << "cncd runs on " << (dir / (name + ".ini")).string() << " (process " << c->pid() << ", log "
            << log.string() << "); cnc-commission shutdown stops it\n";
  c->detach();
  s.log.push_back("controller brought up on " + (dir / (name + ".ini")).string());
  return 0;
}

int cmd_write(State& s, Args& a) {
  std::filesystem::path dir, cncd = self_dir() / "cncd";
  std::string name = "machine";
  bool yes = false;
  while (a.more()) {
    const std::string k = a.next("option");
    if (k == "--dir") dir = a.next("folder");
    else if (k == "--name") name = a.next("name");
    else if (k == "--yes") yes = true;
    else if (k == "--cncd") cncd = a.next("path");
    else usage("write: unknown option " + k);
  }
  if (dir.empty()) usage("write: --dir DIR");
  std::filesystem::create_directories(dir);
  const auto files = generate_config(s, dir, name);
  for (const auto& f : files) {
    std::string old;
    if (std::filesystem::exists(f.path)) {
      std::FILE* in = std::fopen(f.path.c_str(), "r");
      if (in) {
        char buf[4096];
        std::size_t n;
        while ((n = std::fread(buf, 1, sizeof buf, in)) > 0) old.append(buf, n);
        std::fclose(in);
      }
    }
    std::cout << diff_text(f.path.string(), old, f.content);
  }
  if (!yes) {
    std::cout << "(nothing written: --yes writes these files)\n";
    return 0;
  }
  for (const auto& p : write_config(files)) std::cout << "wrote " << p.string() << "\n";
  std::string out;
  const int rc = check_config(cncd, dir / (name + ".ini"), out);
  std::cout << out;
  if (rc != 0) {
    std::cout << "cncd --check --strict failed (status " << rc << "): the old files are kept as .bak\n";
    return 1;
  }
  s.log.push_back("configuration written to " + (dir / (name + ".ini")).string());
  s.config_ini = std::filesystem::absolute(dir / (name + ".ini")).string();
  return 0;
}

// Step 9's check: cncd on the configuration written last, the check
// program run on it (commission/check.hpp). The result is kept in the
// state, passed or not; an abort keeps nothing.
int cmd_check(State& s, Args& a) {
  std::filesystem::path program, bin = self_dir();
  std::optional<double> timeout;
  while (a.more()) {
    const std::string k = a.next("option");
    if (k == "--program") program = a.next("file");
    else if (k == "--timeout") timeout = number(a.next("s"), "--timeout");
    else if (k == "--bin") bin = a.next("folder");
    else usage("check: unknown option " + k);
  }
  if (timeout && !(*timeout > 0)) usage("check: --timeout must be > 0");
  // The written check program's length follows the axes' feeds (a quarter
  // of each MAX_VELOCITY as tuned): a time limit it cannot end within is
  // refused before anything starts.
  if (program.empty()) {
    double needs = 0;
    try {
      needs = check_program_seconds(s);
    } catch (const std::invalid_argument&) {
      // The state no longer makes a check program: the written one runs, unmeasured.
    }
    if (timeout && *timeout < needs) {
      char b[200];
      std::snprintf(b, sizeof b,
                    "check: --timeout %g s: the check program's moves take %.0f s at its feeds (a quarter of each "
                    "axis' MAX_VELOCITY): give at least %.0f s, or none (%.0f s)",
                    *timeout, needs, std::ceil(needs * 1.2), check_default_timeout_s(needs));
      usage(b);
    }
    if (!timeout) timeout = check_default_timeout_s(needs);
  } else if (!timeout) {
    timeout = 600;
  }
  if (s.config_ini.empty())
    throw std::invalid_argument("check: no configuration written yet: run cnc-commission write --dir DIR --yes first");
  const std::filesystem::path ini = s.config_ini;
  if (!std::filesystem::exists(ini))
    throw std::invalid_argument("check: " + ini.string() + " (written last) is not there any more: write it again");
  if (program.empty()) program = ini.parent_path() / "check.ngc";
  program = std::filesystem::absolute(program);
  if (!std::filesystem::exists(program)) throw std::invalid_argument("check: " + program.string() + ": no such program");
  const auto log = ini.parent_path() / "check-cncd.log";
  auto progress = [](int i, int n, const std::string& t) { print_progress(i, n, t); };
  const auto t0 = std::chrono::steady_clock::now();
  CheckRun r;
  r.program = program.string();
  r.ini = ini.string();
  clear_abort();
  try {
    progress(1, 7, "starting cncd on " + ini.string());
    ControllerProcess cncd(bin, ini, log);
    try {
      r.message = run_check(Controller(bin), program, *timeout,
                            [&](int i, int, const std::string& t) { progress(i + 1, 7, t); });
      r.passed = true;
    } catch (const std::exception& e) {
      if (abort_requested()) throw;
      r.message = e.what();
    }
    const int rc = cncd.stop();
    progress(7, 7, "cncd stopped");
    if (rc != 0 && r.passed) {
      r.passed = false;
      r.message += "; but cncd did not end cleanly (status " + std::to_string(rc) + ", see " + log.string() + ")";
    }
  } catch (const std::exception& e) {
    if (abort_requested()) throw std::runtime_error(std::string("aborted: ") + e.what() + " (state unchanged)");
    r.passed = false;  // cncd did not come up
    r.message = e.what();
  }
  r.duration_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.time = utc_now();
  s.check = r;
  s.log.push_back(std::string("check ") + (r.passed ? "passed" : "FAILED") + " on " + ini.string());
  if (!r.passed) {
    std::cout << "check FAILED: " << r.message << "\n(cncd's log: " << log.string() << ")\n";
    return 1;
  }
  std::cout << "check passed: " << r.message << "\n";
  return 0;
}

}  // namespace

extern "C" void on_signal(int) { request_abort(); }

int main(int argc, char** argv) {
  // Ctrl-C during a test move: the move stops, the machine goes off, the
  // step says it was aborted (the state is not changed).
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  Args a;
  std::filesystem::path state_file = "commission.json";
  for (int i = 1; i < argc; ++i) a.v.push_back(argv[i]);
  if (a.v.empty()) usage("no command");
  if (a.v[0] == "--help" || a.v[0] == "-h") {
    std::fputs(kHelp, stdout);
    return 0;
  }
  if (a.v[0] == "--state") {
    a.i = 1;
    state_file = a.next("state file");
  }
  g_state_file = state_file;
  const std::string cmd = a.next("command");
  g_state_dir = std::filesystem::absolute(state_file).parent_path();
  if (cmd == "wizard") {
    // The wizard runs these subcommands itself: it replaces this process.
    const std::string wizard = (self_dir() / "cnc-commission-wizard").string();
    std::vector<std::string> args{wizard, "--state", state_file.string()};
    args.insert(args.end(), a.v.begin() + static_cast<std::ptrdiff_t>(a.i), a.v.end());
    std::vector<char*> argv2;
    for (auto& s : args) argv2.push_back(s.data());
    argv2.push_back(nullptr);
    ::execv(wizard.c_str(), argv2.data());
    std::fprintf(stderr, "cnc-commission: cannot start %s: %s (built only with Qt 6 Widgets and Charts)\n",
                 wizard.c_str(), std::strerror(errno));
    return 1;
  }
  // `cnc-commission CMD ... --help`: the help of every command but the
  // wizard, which has its own (nothing read or written).
  for (std::size_t k = a.i; k < a.v.size(); ++k) {
    if (a.v[k] == "--help" || a.v[k] == "-h") {
      std::fputs(kHelp, stdout);
      return 0;
    }
  }
  try {
    State s = load_state(state_file);
    int rc = 0;
    if (cmd == "scan") rc = cmd_scan(s, a);
    else if (cmd == "lss") rc = cmd_lss(s, a);
    else if (cmd == "scan-ethercat") rc = cmd_scan_ethercat(s, a);
    else if (cmd == "show") {
      show(s);
      return 0;
    } else if (cmd == "axis") rc = cmd_axis(s, a);
    else if (cmd == "include") {
      while (a.more()) {
        const std::string k = a.next("option");
        if (k == "--ini") s.ini_includes.push_back(a.next("file"));
        else if (k == "--hal-before-bus") s.hal_before_bus.push_back(a.next("file"));
        else if (k == "--hal-after-bus") s.hal_after_bus.push_back(a.next("file"));
        else usage("include: unknown option " + k);
      }
    } else if (cmd == "homing-methods") {  // step 6
      for (const auto& m : homing_methods()) std::printf("%-11s %s\n", m.id.c_str(), m.text.c_str());
      return 0;
    } else if (cmd == "write") rc = cmd_write(s, a);
    else if (cmd == "bring-up") rc = cmd_bring_up(s, a);
    else if (cmd == "backup") rc = cmd_backup(s, a);
    else if (cmd == "restore") rc = cmd_restore(s, a);
    else if (cmd == "check") rc = cmd_check(s, a);
    else if (cmd == "shutdown") {
      Controller(self_dir()).cnc({"shutdown"});
      return 0;
    }
    else usage("unknown command " + cmd);
    save_state(s, state_file);
    return rc;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cnc-commission: %s\n", e.what());
    return 1;
  }
}
