#include "commission/config_writer.hpp"

#include "commission/check.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <sys/wait.h>

#include "commission/backup.hpp"
#include "commission/compensation.hpp"
#include "commission/homing_check.hpp"  // steps 5, 6: homing keys, switch nets
#include "commission/steps.hpp"  // machine_joints
#include "core/util/atomic_file.hpp"

namespace cnc::commission {

namespace {

std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.10g", v);
  return b;
}

std::string read_text(const std::filesystem::path& p) {
  std::ifstream in(p);
  if (!in) return {};
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::vector<std::string> lines_of(const std::string& t) {
  std::vector<std::string> v;
  std::stringstream ss(t);
  std::string l;
  while (std::getline(ss, l)) v.push_back(l);
  return v;
}

}  // namespace

// The drive's torque limit 0x6072 as the scan read it (the tuning step
// measured saturation against it): written back at every start-up so the
// configuration holds the limit the axis was tuned with.
static std::string max_torque_key(const State& s, const Axis& a) {
  const std::optional<double> pct = drive_max_torque_pct(s, a);
  if (!pct) return "";
  char b[96];
  std::snprintf(b, sizeof b, "# The drive's 0x6072 as scanned (the tuning's torque limit).\nMAX_TORQUE = %g\n", *pct);
  return b;
}

long servo_period_ns(std::size_t drives) noexcept {
  return static_cast<long>(1'000'000 * std::max<std::size_t>(1, (drives + 1) / 2));
}

// Step 7's loop response on axis `a` (WriterOptions::response_axis): a
// signal generator on its drive's velocity command.
static std::string response_hal(const Axis& a) {
  char d[64];
  std::snprintf(d, sizeof d, "cia402.0.drive.%02d.", a.joint);
  return "\n# cnc-commission axis " + std::string(1, a.letter) +
         " response: a signal generator on the drive's velocity command\n"
         "# (used in CSV only; sel 0 sine, 1 square).\n"
         "addf response.update servo-thread\naddf response-mux servo-thread\n"
         "setp response.amplitude 0\nsetp response.reset 1\n"
         "net response-sine response.sine => response-mux.in0\n"
         "net response-square response.square => response-mux.in1\n"
         "net response-vel response-mux.out => " + std::string(d) + "vel-cmd\n";
}

// The response's components (both generators: a component is loaded
// once), and the position loop's generator: an offset added to the joint's
// position command on its way to the drive (CSP; quiet, the command passes
// unchanged), in the thread before the drives' write so the offset goes
// out in the cycle it is made. (The velocity loop's functions come last in
// the thread: response_hal.)
static std::string response_position_hal() {
  return "# cnc-commission response: signal generators on the drive's velocity command\n"
         "# (below) and added to its position command (the position loop, in CSP;\n"
         "# sel 0 sine, 1 square).\n"
         "loadrt siggen names=response,response-pos\nloadrt mux2 names=response-mux,response-pos-mux\n"
         "loadrt sum2 names=response-pos-sum\n"
         "addf response-pos.update servo-thread\naddf response-pos-mux servo-thread\naddf response-pos-sum servo-thread\n"
         "setp response-pos.amplitude 0\nsetp response-pos.reset 1\n"
         "net response-pos-sine response-pos.sine => response-pos-mux.in0\n"
         "net response-pos-square response-pos.square => response-pos-mux.in1\n"
         "net response-pos-offset response-pos-mux.out => response-pos-sum.in1\n";
}

static constexpr const char* kResponseComment = "# cnc-commission response: the target velocity for CSV\n";

std::vector<GeneratedFile> generate_config(const State& s, const std::filesystem::path& dir, const std::string& name,
                                           const WriterOptions& options) {
  const bool gantry_joints_apart = options.gantry_joints_apart;
  // The axes (one [AXIS_L] each) and the joints (one [JOINT_n], drive and
  // node each): a gantry pair is one axis on two joints (steps.hpp,
  // machine_joints).
  std::vector<const Axis*> axes;
  for (const Axis& a : s.axes) axes.push_back(&a);
  if (axes.empty()) throw std::invalid_argument("no axis: assign a drive to an axis first");
  std::sort(axes.begin(), axes.end(), [](const Axis* a, const Axis* b) { return a->joint < b->joint; });
  const std::vector<MachineJoint> joints = machine_joints(s);
  for (std::size_t i = 0; i < joints.size(); ++i) {
    const Axis& a = joints[i].axis;
    if (a.joint != static_cast<int>(i))
      throw std::invalid_argument(std::string("axis ") + a.letter + (joints[i].gantry_second ? "'s gantry drive" : "") +
                                  " is on joint " + std::to_string(a.joint) + ": the axes must use joints 0.." +
                                  std::to_string(joints.size() - 1));
    if (a.enabled && !(a.scaling.counts_per_mm() > 0))
      throw std::invalid_argument(std::string("axis ") + a.letter + " has no scaling yet: run its scaling step");
  }
  std::vector<const Axis*> joint_axes;  // each joint's drive, in joint order
  for (const MachineJoint& j : joints) joint_axes.push_back(&j.axis);
  bool gantry = false;
  for (const Axis* a : axes) gantry = gantry || a->gantry.has_value();
  // One bus for all axes: CANopen drives (node-IDs) or EtherCAT drives
  // (slave positions).
  const bool ethercat = axes.front()->slave > 0;
  for (const Axis* a : joint_axes) {
    if ((a->slave > 0) != ethercat)
      throw std::invalid_argument(std::string("axis ") + a->letter + " is on " + (ethercat ? "CANopen" : "EtherCAT") +
                                  " and axis " + axes.front()->letter + " on " + (ethercat ? "EtherCAT" : "CANopen") +
                                  ": the writer puts every axis on one bus");
  }
  if (!ethercat && s.interface.empty()) throw std::invalid_argument("no CAN interface in the state: run the bus scan first");
  if (ethercat && s.ethercat_interface.empty())
    throw std::invalid_argument("no EtherCAT interface in the state: run scan-ethercat first");
  const Axis* response = options.response_axis ? s.axis(options.response_axis) : nullptr;
  if (options.response_axis && !response)
    throw std::invalid_argument(std::string("axis ") + options.response_axis + " has no drive yet: no loop response on it");
  const std::string bus = ethercat ? "ethercat.0" : "canopen.0";
  // Names of the joints' drives, nets and nodes: "y", and "y2" for a
  // gantry's second drive.
  const auto short_name = [&joints](std::size_t i) {
    return std::string(1, static_cast<char>(std::tolower(joints[i].axis.letter))) + (joints[i].gantry_second ? "2" : "");
  };
  // A gantry pair homes together: both joints the same negative
  // HOME_SEQUENCE (-1 for the first pair, -2 for the next ...), the other
  // joints keep theirs (0).
  const auto home_sequence = [&axes, gantry_joints_apart](const Axis& a) {
    if (gantry_joints_apart) return 0;
    int pair = 0;
    for (const Axis* x : axes) {
      if (x->gantry) ++pair;
      if (x->letter == a.letter) return a.gantry ? -pair : 0;
    }
    return 0;
  };

  std::string coords, drives, nodes;
  for (std::size_t i = 0; i < joints.size(); ++i) {
    const Axis& a = joints[i].axis;
    coords += (i ? " " : "") + std::string(1, a.letter);
    drives += (i ? " " : "") + std::to_string(i);
    nodes += (i ? " " : "") + std::to_string(ethercat ? a.slave : a.node);
  }
  // Step 7 (tuning): an axis' recommended limits replace its provisional
  // ones (joint and axis), with its FERROR, MIN_FERROR and MAX_JERK.
  struct Limits {
    double v, a, jerk, ferror, min_ferror;
  };
  auto limits = [](const Axis& a) {
    Limits l{a.max_velocity, a.max_acceleration, 0, 1.0, 0.2};
    if (a.tuning && a.tuning->max_velocity > 0 && a.tuning->max_acceleration > 0) {
      l = {a.tuning->max_velocity, a.tuning->max_acceleration, a.tuning->max_jerk, a.tuning->ferror, a.tuning->min_ferror};
    }
    return l;
  };
  double max_v = 0, max_a = 0;
  for (const Axis* a : axes) {
    max_v = std::max(max_v, limits(*a).v);
    max_a = std::max(max_a, limits(*a).a);
  }

  std::ostringstream ini;
  ini << "# Generated by cnc-commission from its state file; edit the state\n"
         "# (cnc-commission ...) and write again rather than this file.\n"
         "# Machine units: mm, mm/s, mm/s^2.\n\n"
      << "[EMC]\nVERSION = 1.1\nMACHINE = " << s.machine << "\n\n"
      << "[DISPLAY]\nTITLE = " << s.machine << "\nPROGRAM_PREFIX = nc_files\n\n"
      << "[TASK]\nTASK = milltask\nCYCLE_TIME = 0.001\n\n"
      << "[RS274NGC]\nPARAMETER_FILE = " << name << ".var\n\n"
      << "[EMCMOT]\nEMCMOT = motmod\n"
      << (ethercat ? "# One EtherCAT frame per millisecond carries every drive.\n"
                   : "# Two axis drives per millisecond fit one 1 Mbit/s bus (cnc-canopen load prints the plan).\n")
      << "SERVO_PERIOD = " << (ethercat ? 1'000'000L : servo_period_ns(joints.size())) << "\nCOMM_TIMEOUT = 1.0\n\n"
      << "[HAL]\nHALFILE = " << name << ".hal\n\n"
      << "[TRAJ]\nCOORDINATES = " << coords << "\nLINEAR_UNITS = mm\nANGULAR_UNITS = degree\n"
      << "MAX_LINEAR_VELOCITY = " << num(max_v) << "\nMAX_LINEAR_ACCELERATION = " << num(max_a) << "\n\n"
      << (gantry ? "# A gantry: a letter twice, its two joints homed and jogged apart in joint mode (kinstype=BOTH).\n" : "")
      << (gantry && gantry_joints_apart
              ? "# Commissioning the gantry's drives: the pair's joints are not homed together (HOME_SEQUENCE 0).\n"
              : "")
      << "[KINS]\nKINEMATICS = trivkins coordinates=" << [&] {
           std::string c;
           for (const Axis* a : joint_axes) c += a->letter;
           return c;
         }() << (gantry ? " kinstype=BOTH" : "") << "\nJOINTS = " << joints.size() << "\n\n";
  for (const Axis* a : axes) {
    const Limits l = limits(*a);
    ini << "[AXIS_" << a->letter << "]\nMIN_LIMIT = " << num(a->min_limit) << "\nMAX_LIMIT = " << num(a->max_limit)
        << "\nMAX_VELOCITY = " << num(l.v) << "\nMAX_ACCELERATION = " << num(l.a) << "\n";
    if (l.jerk > 0) ini << "MAX_JERK = " << num(l.jerk) << "\n";
    if (a->tuning && a->tuning->margin_pct > 0 && !a->tuning->tests.empty())
      ini << "# Tuned: the highest clean test less " << num(a->tuning->margin_pct) << " % (cnc-commission axis "
          << a->letter << " tune)\n";
    ini << "\n";
  }
  for (const MachineJoint& mj : joints) {
    // Homing: as step 6 chose it; not commissioned yet, the joint takes
    // its position where it stands (HOME_SEARCH_VEL 0). Limits: step 7's
    // recommendations when tuned. A gantry's two joints have the axis'
    // limits and homing, and one negative HOME_SEQUENCE.
    const Axis* a = &mj.axis;
    const Limits l = limits(*a);
    if (mj.gantry_second && a->gantry->reverse && a->homing && drive_method(a->homing->method) > 0)
      throw std::invalid_argument(std::string("axis ") + a->letter + ": the gantry's second drive turns the other way, so the drive homing method " +
                                  a->homing->method + " would search the other side on it: home the gantry with the controller's sequence (homing --method controller)");
    std::string homing = joint_homing_keys(*a);  // steps 5, 6
    if (const int seq = home_sequence(*a); seq != 0) {
      const std::string key = "HOME_SEQUENCE = 0\n";
      const auto at = homing.find(key);
      if (at == std::string::npos) throw std::logic_error("joint_homing_keys wrote no HOME_SEQUENCE = 0");
      homing.replace(at, key.size(), "HOME_SEQUENCE = " + std::to_string(seq) + "\n");
    }
    if (mj.gantry_second)
      ini << "# Axis " << a->letter << ", the gantry's second drive" << (a->gantry->reverse ? " (reversed)" : "")
          << ": homed together with joint " << s.axis(a->letter)->joint << ".\n";
    else if (a->gantry)
      ini << "# Axis " << a->letter << ", the gantry's first drive: homed together with joint " << a->gantry->joint
          << ".\n";
    ini << "[JOINT_" << a->joint << "]\nTYPE = LINEAR\nMIN_LIMIT = " << num(a->min_limit)
        << "\nMAX_LIMIT = " << num(a->max_limit) << "\nMAX_VELOCITY = " << num(l.v * 1.05)
        << "\nMAX_ACCELERATION = " << num(l.a * 1.1) << "\n";
    if (l.jerk > 0) ini << "MAX_JERK = " << num(l.jerk * 1.1) << "\n";
    ini << "FERROR = " << num(l.ferror) << "\nMIN_FERROR = " << num(l.min_ferror) << "\n"
        << homing                              // steps 5, 6
        << comp_ini_keys(*a, name) << "\n";  // step 8: the screw-compensation table, when installed
  }
  ini << "[EMCIO]\nEMCIO = io\nTOOL_TABLE = tool.tbl\nTOOL_PREPARE_TIMEOUT = 10\nTOOL_CHANGE_TIMEOUT = 30\n\n";
  if (ethercat) {
    // Cycles without valid process data ridden through, as PDO_MISS_LIMIT
    // on CANopen and STALE_LIMIT below: a host without a realtime kernel
    // stalls for several ms now and then; the drives' own sync-manager
    // watchdog (100 ms) still stops them if the master is gone.
    ini << "[ETHERCAT]\nINTERFACE = " << s.ethercat_interface << "\nSLAVE = " << nodes
        << "\n# Cycles without valid process data ridden through (3 on a realtime kernel).\nMISS_LIMIT = 50\n\n";
    for (std::size_t i = 0; i < joints.size(); ++i) {
      const Axis* a = &joints[i].axis;
      const ScannedSlave* sl = nullptr;
      for (const ScannedSlave& x : s.slaves)
        if (static_cast<int>(x.position) == a->slave) sl = &x;
      char id[64];
      std::snprintf(id, sizeof id, "VENDOR_ID = 0x%08X\nPRODUCT_CODE = 0x%08X\n", sl ? sl->vendor_id : 0u,
                    sl ? sl->product_code : 0u);
      ini << "[ETHERCAT_SLAVE_" << a->slave << "]\nNAME = " << short_name(i) << "-axis\n";
      if (sl && !sl->esi.empty() && !s.esi_dir.empty())
        ini << "ESI = " << (std::filesystem::path(s.esi_dir) / sl->esi).string() << "\n";
      if (sl) ini << id;
      // The inputs the controller and commissioning read every cycle, as
      // the CANopen nodes' TPDOs carry them: torque (tuning), the digital
      // inputs (limit and home switches), the mode shown and the error code.
      ini << "TXPDO = 0x6041:0:u16 0x6064:0:s32 0x606C:0:s32 0x6077:0:s16 0x60FD:0:u32 0x6061:0:s8 0x603F:0:u16\n";
      if (response && a->slave == response->slave) ini << kResponseComment << "RXPDO = " << kResponseEthercatRxPdo << "\n";
      if (!a->enabled) ini << "# Disabled for commissioning: it may be missing.\n";
      ini << "\n";
    }
  } else {
  // The response reaches its drive by SDO through the shared socket of a
  // virtual bus while cncd runs (response_sdo_interface).
  const bool share = response && s.interface.rfind("virtual:", 0) == 0 && s.interface.find("share") == std::string::npos;
  ini << "[CANOPEN]\nINTERFACE = " << s.interface << (share ? ",share" : "") << "\nBITRATE = " << s.bitrate << "\nNODE = " << nodes
      << "\nMASTER_HEARTBEAT_MS = 100\nPDO_MISS_LIMIT = 50\n\n";
  for (std::size_t i = 0; i < joints.size(); ++i) {
    const Axis* a = &joints[i].axis;
    const ScannedNode* n = s.node(a->node);
    ini << "[CANOPEN_NODE_" << a->node << "]\nNAME = " << short_name(i) << "-axis\n";
    if (n && !n->eds.empty() && !s.eds_dir.empty())
      ini << "# " << (std::filesystem::path(s.eds_dir) / n->eds).string() << " describes this drive\n";
    if (!a->enabled) ini << "# Disabled for commissioning: it may be missing.\nMANDATORY = NO\n";
    ini << "HEARTBEAT_MS = 100\nHEARTBEAT_TIMEOUT_MS = 3000\nMASTER_HEARTBEAT_TIMEOUT_MS = 2000\n"
           "RPDO1 = 0x6040:0:u16 0x607A:0:s32\n";
    if (response && a->node == response->node) ini << kResponseComment << "RPDO2 = " << kResponseCanopenRpdo << "\n";
    ini << "TPDO1 = 0x6041:0:u16 0x6064:0:s32 0x6077:0:s16\n"
           "TPDO2 = 0x6061:0:s8 0x60FD:0:u32 0x603F:0:u16\nTPDO2_TRANSMISSION = 255\n"
           "TPDO2_INHIBIT_100US = 20\nTPDO2_EVENT_MS = 100\n\n";
  }
  }
  ini << "[CIA402]\nBUS = " << bus << "\nDRIVE = " << drives << "\nWATCHDOG_CYCLES = 5\nSTALE_LIMIT = 50\n\n";
  for (std::size_t i = 0; i < joints.size(); ++i) {
    const Axis& a = joints[i].axis;
    AxisScaling sc = a.scaling;
    if (!(sc.counts_per_mm() > 0)) {  // a disabled axis not scaled yet: any scaling will do
      sc.encoder_counts = 1000;
      sc.screw_lead = 1;
      sc.correction = 1;
      sc.source = "not scaled yet";
    }
    // The measured correction is folded into the lead: counts per mm =
    // ENCODER_COUNTS x GEAR_MOTOR_REVS / GEAR_LOAD_REVS / SCREW_LEAD.
    ini << "[CIA402_DRIVE_" << i << "]\n# " << sc.source << "; " << num(sc.counts_per_mm()) << " counts/mm";
    if (sc.correction != 1.0) ini << " (nominal lead " << num(sc.screw_lead) << " mm, measured x" << num(sc.correction) << ")";
    ini << "\nADDRESS = " << (ethercat ? a.slave : a.node) << "\nNAME = " << short_name(i) << "-axis\nJOINT = "
        << a.joint << "\nENCODER_COUNTS = " << num(sc.encoder_counts) << "\nGEAR_MOTOR_REVS = "
        << num(sc.gear_motor_revs) << "\nGEAR_LOAD_REVS = " << num(sc.gear_load_revs)
        << "\nSCREW_LEAD = " << num(sc.screw_lead / sc.correction) << "\nREVERSE = " << (sc.reverse ? "YES" : "NO")
        << "\nPROBE = NO\n" << max_torque_key(s, a) << drive_homing_keys(a) << (a.enabled ? "" : "DISABLED = YES\n") << "FERROR_WINDOW = 1\nFERROR_TIMEOUT_MS = 20\nQUICK_STOP_DECEL = "
        << num(a.tuning && a.tuning->max_acceleration > 0  // tuned: the highest clean test's acceleration
                   ? limits(a).a / (1 - a.tuning->margin_pct / 100)
                   : a.max_acceleration * 2)
        << "\n\n";
  }
  for (const auto& inc : s.ini_includes) ini << "#INCLUDE " << inc << "\n";

  std::ostringstream hal;
  hal << "# Generated by cnc-commission: the motion controller, the CANopen\n"
         "# master and the CiA 402 drives of the commissioned axes.\n\n"
         "loadrt [KINS]KINEMATICS\n"
         "loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS\n";
  if (any_compensation(s)) hal << "# Screw compensation tables ([JOINT_n]COMP_FILE).\nloadrt screwcomp\n";
  for (const auto& f : s.hal_before_bus) hal << "source " << f << "\n";
  hal << (ethercat ? "loadrt ethercat\n" : "loadrt canopen buses=CANOPEN\n") << "loadrt cia402 sections=CIA402\n\n"
      << "addf " << bus << ".read servo-thread\naddf cia402.0.read servo-thread\n"
      << "addf motion-command-handler servo-thread\naddf motion-controller servo-thread\n";
  if (response) hal << response_position_hal();
  hal << "addf cia402.0.write servo-thread\naddf " << bus << ".write servo-thread\n";
  for (const auto& f : s.hal_after_bus) hal << "source " << f << "\n";
  // The scope records the tuning tests (step 7) every servo cycle; last in
  // the thread so it sees the cycle's values.
  hal << "loadrt scope samples=60000\naddf scope.sample servo-thread\n\n";
  for (std::size_t i = 0; i < joints.size(); ++i) {
    const Axis& a = joints[i].axis;
    char d[64];
    std::snprintf(d, sizeof d, "cia402.0.drive.%02zu.", i);
    const std::string j = "joint." + std::to_string(a.joint) + ".";
    const std::string l = short_name(i);
    if (response && a.joint == response->joint)
      hal << "net " << l << "-pos-cmd " << j << "motor-pos-cmd => response-pos-sum.in0\n"
          << "net " << l << "-pos-cmd-response response-pos-sum.out => " << d << "pos-cmd\n";
    else
      hal << "net " << l << "-pos-cmd " << j << "motor-pos-cmd => " << d << "pos-cmd\n";
    hal << "net " << l << "-pos-fb " << d << "pos-fb => " << j << "motor-pos-fb\n"
        << "net " << l << "-enable " << j << "amp-enable-out => " << d << "enable\n"
        << "net " << l << "-fault " << d << "amp-fault => " << j << "amp-fault-in\n"
        << "net " << l << "-ready " << d << "enabled => " << j << "amp-ready-in\n";
  }
  hal << switch_nets(joint_axes);  // steps 5, 6 (a gantry's second drive: its own switches, the axis' polarity)
  hal << "\n# The drives stop by themselves when the motion watchdog stops.\n"
         "net watchdog motion.watchdog => cia402.0.watchdog\n"
         "net watchdog-on motion.watchdog-enabled => cia402.0.watchdog-enabled\n"
         "net bus-0-enable cia402.0.watchdog-ok => " << bus << ".enable\n\n"
      << "# E-stop: wire your E-stop chain to iocontrol.0.emc-enable-in (here it closes at once).\n"
         "net estop-loop iocontrol.0.user-enable-out => iocontrol.0.emc-enable-in\n"
         "# Tool changes: acknowledged at once (a manual change).\n"
         "net tool-prepare-loop iocontrol.0.tool-prepare => iocontrol.0.tool-prepared\n"
         "net tool-change-loop iocontrol.0.tool-change => iocontrol.0.tool-changed\n";
  if (response) hal << response_hal(*response);

  std::vector<GeneratedFile> out;
  out.push_back({dir / (name + ".ini"), ini.str()});
  out.push_back({dir / (name + ".hal"), hal.str()});
  if (!std::filesystem::exists(dir / "tool.tbl"))
    out.push_back({dir / "tool.tbl",
                   "T1 P1 D6.000 Z+35.000 ;6 mm end mill\nT2 P2 D10.000 Z+42.500 ;10 mm end mill\n"
                   "T3 P3 D5.000 Z+55.000 ;5 mm drill\n"});
  // Step 9's check program (cnc-commission check runs it on this configuration).
  out.push_back({dir / "check.ngc", check_program(s)});
  // Steps 8 and 9: compensation tables, and the drive-parameter backup when one was taken.
  for (auto& f : compensation_files(s, dir, name)) out.push_back(std::move(f));
  for (auto& f : backup_files(s, dir)) out.push_back(std::move(f));
  return out;
}

std::string diff_text(const std::string& file, const std::string& old_text, const std::string& new_text) {
  if (old_text == new_text) return {};
  const auto a = lines_of(old_text), b = lines_of(new_text);
  // Longest common subsequence (configuration files are small).
  const std::size_t n = a.size(), m = b.size();
  std::vector<std::vector<uint32_t>> l(n + 1, std::vector<uint32_t>(m + 1, 0));
  for (std::size_t i = n; i-- > 0;)
    for (std::size_t j = m; j-- > 0;) l[i][j] = a[i] == b[j] ? l[i + 1][j + 1] + 1 : std::max(l[i + 1][j], l[i][j + 1]);
  std::string out = "--- " + file + (old_text.empty() ? " (new)" : "") + "\n+++ " + file + "\n";
  std::size_t i = 0, j = 0;
  while (i < n || j < m) {
    if (i < n && j < m && a[i] == b[j]) {
      ++i;
      ++j;
    } else if (i < n && (j == m || l[i + 1][j] >= l[i][j + 1])) {
      out += "-" + a[i++] + "\n";
    } else {
      out += "+" + b[j++] + "\n";
    }
  }
  return out;
}

std::vector<std::filesystem::path> write_config(const std::vector<GeneratedFile>& files) {
  std::vector<std::filesystem::path> changed;
  for (const auto& f : files) {
    const bool exists = std::filesystem::exists(f.path);
    const std::string old = exists ? read_text(f.path) : std::string();
    if (exists && old == f.content) continue;
    if (exists) write_file_atomically(f.path.string() + ".bak", old);
    if (!exists && f.path.has_parent_path()) std::filesystem::create_directories(f.path.parent_path());
    write_file_atomically(f.path, f.content);
    changed.push_back(f.path);
  }
  return changed;
}

int check_config(const std::filesystem::path& cncd, const std::filesystem::path& ini, std::string& output) {
  const std::string cmd = "'" + cncd.string() + "' --check --strict '" + ini.string() + "' 2>&1";
  FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) {
    output = "cannot run " + cncd.string();
    return 127;
  }
  std::array<char, 512> buf{};
  while (std::fgets(buf.data(), buf.size(), p)) output += buf.data();
  const int st = ::pclose(p);
  return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

}  // namespace cnc::commission
