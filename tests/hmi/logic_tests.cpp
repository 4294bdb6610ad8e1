// The screen's logic without widgets: number entry, INI reading, the jog
// state machine, MDI history, alarms, positions and touch-off, command
// tracking, the preview path and the HAL-driven user dialogs.
#include <QTemporaryDir>
#include <QtTest>
#include <cmath>
#include <fstream>

#include "core/ini/ini_file.hpp"
#include "core/util/atomic_file.hpp"
#include "fake_link.hpp"
#include "hmi/alarms.hpp"
#include "hmi/commands.hpp"
#include "hmi/config.hpp"
#include "hmi/jog.hpp"
#include "hmi/mdi_history.hpp"
#include "hmi/numbers.hpp"
#include "hmi/positions.hpp"
#include "hmi/preview_path.hpp"
#include "hmi/readouts.hpp"
#include "hmi/trends.hpp"
#include "hmi/user_dialogs.hpp"

using namespace cnc;
using namespace cnc::hmi;
using cnc::hmi::testing::FakeLink;
using ipc::CommandType;

namespace {

std::string write(const QTemporaryDir& dir, const std::string& name, const std::string& text) {
  const std::string path = dir.path().toStdString() + "/" + name;
  std::ofstream(path) << text;
  return path;
}

ipc::Status on_status(bool homed, ipc::TaskMode mode = ipc::TaskMode::Manual) {
  FakeLink f;
  f.set_on(homed, mode);
  return f.status;
}

}  // namespace

class LogicTests : public QObject {
  Q_OBJECT
 private slots:
  // ---------------------------------------------------------------- numbers
  void numbers_accept_comma_or_point() {
    QCOMPARE(*parse_operator_number("12.5"), 12.5);
    QCOMPARE(*parse_operator_number("12,5"), 12.5);
    QCOMPARE(*parse_operator_number(" -0,25 "), -0.25);
    QCOMPARE(*parse_operator_number(".5"), 0.5);
    QCOMPARE(*parse_operator_number(",5"), 0.5);
    QCOMPARE(*parse_operator_number("-,5"), -0.5);
    QCOMPARE(*parse_operator_number("7."), 7.0);
    QCOMPARE(*parse_operator_number("+3"), 3.0);
    QCOMPARE(*parse_operator_number("42"), 42.0);
  }
  void numbers_refuse_two_separators_and_garbage() {
    std::string why;
    QVERIFY(!parse_operator_number("1,5.3", &why));
    QVERIFY(QString::fromStdString(why).contains("comma and a point"));
    QVERIFY(!parse_operator_number("1.2.3", &why));
    QVERIFY(QString::fromStdString(why).contains("more than one"));
    QVERIFY(!parse_operator_number("1,,5"));
    QVERIFY(!parse_operator_number("1 5"));
    QVERIFY(!parse_operator_number("1e3"));
    QVERIFY(!parse_operator_number(""));
    QVERIFY(!parse_operator_number("-"));
    QVERIFY(!parse_operator_number("abc"));
    QVERIFY(!parse_operator_number("5-"));
    QVERIFY(is_partial_operator_number("-"));
    QVERIFY(is_partial_operator_number("1,"));
    QVERIFY(!is_partial_operator_number("1,2,"));
  }
  void numbers_are_shown_with_one_separator() {
    const NumberFormat point('.'), comma(',');
    QCOMPARE(point.fixed(1.5, 3), std::string("1.500"));
    QCOMPARE(comma.fixed(1.5, 3), std::string("1,500"));
    QCOMPARE(comma.fixed(-1234.56789, 2), std::string("-1234,57"));
    QCOMPARE(point.fixed(-0.0001, 3), std::string("0.000"));  // no "-0.000"
    QCOMPARE(point.fixed_width(3, 1, 6), std::string("   3.0"));
    // What the screen shows, it reads back.
    QCOMPARE(*parse_operator_number(comma.fixed(-12.125, 3)), -12.125);
  }

  // ---------------------------------------------------------------- config
  void config_reads_display_keys() {
    QTemporaryDir dir;
    const std::string ini = write(dir, "m.ini",
                                  "[EMC]\nMACHINE = Test mill\n"
                                  "[DISPLAY]\nTITLE = My mill\nICON = mill.png\nCYCLE_TIME = 0.05\n"
                                  "INCREMENTS = 1 mm, 0.1 inch, 1/8 inch, .5mm, 2 furlongs\n"
                                  "ANGULAR_INCREMENTS = continuous, .5, 45\n"
                                  "DEFAULT_LINEAR_VELOCITY = 1200/min\nMAX_LINEAR_VELOCITY = 50\nMIN_LINEAR_VELOCITY = 0.5\n"
                                  "MAX_FEED_OVERRIDE = 120\nMIN_SPINDLE_0_OVERRIDE = 0.5\nMAX_SPINDLE_0_OVERRIDE = 150%\n"
                                  "DRO_FORMAT_MM = %10.4f\nPOSITION_FEEDBACK = ACTUAL\nMDI_HISTORY_FILE = hist.txt\n"
                                  "EMBED_TAB_NAME = Panel\nEMBED_TAB_COMMAND = panel -x {XID}\nEMBED_TAB_LOCATION = tabs\n"
                                  "[TRAJ]\nCOORDINATES = X Y Z\nLINEAR_UNITS = mm\nMAX_LINEAR_VELOCITY = 100\n"
                                  "[KINS]\nKINEMATICS = trivkins coordinates=XYZ\nJOINTS = 3\n"
                                  "[AXIS_X]\nMIN_LIMIT = -1\nMAX_LIMIT = 300\n"
                                  "[HAL]\nPOSTGUI_HALFILE = post.hal\nPOSTGUI_HALCMD = show pin hmi\n"
                                  "[FILTER]\nPROGRAM_EXTENSION = .ngc,.nc G-code\nPROGRAM_EXTENSION = .png Depth image\npng = image-to-gcode\n"
                                  "[MDI_COMMAND_LIST]\nMDI_COMMAND_MACRO0 = G0 Z0;G0 X0 Y0, Go\\nhome\nMDI_COMMAND_MACRO1 = M3 S100\n");
    const HmiConfig c = HmiConfig::from_ini(ini::IniFile::load(ini));
    QCOMPARE(c.title, std::string("My mill"));
    QCOMPARE(c.icon.filename().string(), std::string("mill.png"));
    QVERIFY(c.icon.is_absolute());
    QCOMPARE(c.cycle_time_ms, 50);
    QCOMPARE(c.increments.size(), std::size_t(5));  // continuous + 4 (furlongs refused)
    QVERIFY(c.increments[0].continuous);
    QCOMPARE(c.increments[1].distance, 1.0);
    QVERIFY(std::fabs(c.increments[2].distance - 2.54) < 1e-12);
    QVERIFY(std::fabs(c.increments[3].distance - 3.175) < 1e-12);
    QCOMPARE(c.increments[4].distance, 0.5);
    QCOMPARE(c.angular_increments.size(), std::size_t(3));
    QCOMPARE(c.angular_increments[2].distance, 45.0);
    QCOMPARE(c.default_linear_velocity, 20.0);
    QCOMPARE(c.max_linear_velocity, 50.0);
    QCOMPARE(c.min_linear_velocity, 0.5);
    QCOMPARE(c.max_feed_override, 1.2);
    QCOMPARE(c.min_spindle_override, 0.5);
    QCOMPARE(c.max_spindle_override, 1.5);
    QCOMPARE(c.dro_decimals_mm, 4);
    QVERIFY(c.position_feedback_actual);
    QCOMPARE(c.mdi_history_file, std::filesystem::path(dir.path().toStdString()) / "hist.txt");
    QCOMPARE(c.embed_tabs.size(), std::size_t(1));
    QCOMPARE(c.embed_tabs[0].command, std::string("panel -x {XID}"));
    QCOMPARE(c.postgui_halfiles.size(), std::size_t(1));
    QCOMPARE(c.postgui_halfiles[0], std::filesystem::path(dir.path().toStdString()) / "post.hal");
    QCOMPARE(c.postgui_halcmds.at(0), std::string("show pin hmi"));
    QCOMPARE(c.program_filters.size(), std::size_t(2));
    QCOMPARE(c.program_filters[0].extensions, (std::vector<std::string>{"ngc", "nc"}));
    QCOMPARE(c.program_filters[1].description, std::string("Depth image"));
    QVERIFY(c.filter_for("part.PNG"));
    QCOMPARE(c.filter_for("part.PNG")->program, std::string("image-to-gcode"));
    QVERIFY(!c.filter_for("part.ngc"));
    QCOMPARE(c.macros.size(), std::size_t(2));
    QCOMPARE(c.macros[0].commands, std::string("G0 Z0;G0 X0 Y0"));
    QCOMPARE(c.macros[0].label, std::string("Go\nhome"));
    QCOMPARE(c.macros[1].label, std::string("M3 S100"));
    QCOMPARE(c.axes.size(), std::size_t(3));
    QCOMPARE(c.axes[0].max_limit, 300.0);
    bool furlong_warned = false;
    for (const auto& w : c.warnings) furlong_warned = furlong_warned || w.find("furlongs") != std::string::npos;
    QVERIFY(furlong_warned);
  }
  void config_units_and_ambiguities() {
    // Cycle time in milliseconds, too fast: limited; percent vs ratio; jog speed above the machine.
    const auto c = HmiConfig::from_ini(ini::IniFile::parse(
        "[DISPLAY]\nCYCLE_TIME = 5\nMAX_LINEAR_VELOCITY = 500\nINCREMENTS = 0.1 mm 0.01 mm\n"
        "[TRAJ]\nLINEAR_UNITS = inch\nMAX_LINEAR_VELOCITY = 4\n"));
    QCOMPARE(c.cycle_time_ms, 20);
    QVERIFY(c.machine_inch);
    QCOMPARE(c.max_linear_velocity, 4.0);
    QVERIFY(std::fabs(c.increments[1].distance - 0.1 / 25.4) < 1e-12);  // mm on an inch machine
    QCOMPARE(c.increments.size(), std::size_t(3));  // blank-separated works too
    QVERIFY(c.warnings.size() >= 2);
    bool ok = false;
    QCOMPARE(parse_override_limit("1.5", ok), 1.5);
    QVERIFY(ok);
    QCOMPARE(parse_override_limit("150", ok), 1.5);
    QCOMPARE(parse_override_limit("80%", ok), 0.8);
    parse_override_limit("fast", ok);
    QVERIFY(!ok);
    QCOMPARE(parse_jog_velocity("600 per minute", ok), 10.0);
    QCOMPARE(parse_jog_velocity("20/s", ok), 20.0);
    QCOMPARE(parse_dro_format("%9.3f"), 3);
    QCOMPARE(parse_dro_format("%f"), -1);
  }
  void config_machine_type_and_joints() {
    const auto lathe = HmiConfig::from_ini(ini::IniFile::parse(
        "[DISPLAY]\nMACHINE_TYPE_HINT = LATHE\n[TRAJ]\nCOORDINATES = XZ\n[KINS]\nKINEMATICS = trivkins coordinates=XZ\nJOINTS = 2\n"));
    QVERIFY(lathe.lathe);
    QCOMPARE(lathe.axes.size(), std::size_t(2));
    QCOMPARE(lathe.axes[1].letter, 'Z');
    QCOMPARE(lathe.joints[1].axis, 2);
    const auto old_style = HmiConfig::from_ini(ini::IniFile::parse("[DISPLAY]\nLATHE = 1\n"));
    QVERIFY(old_style.lathe);
    // A gantry: two joints on Y.
    const auto gantry = HmiConfig::from_ini(ini::IniFile::parse(
        "[TRAJ]\nCOORDINATES = XYZ\n[KINS]\nKINEMATICS = trivkins coordinates=XYYZ kinstype=BOTH\nJOINTS = 4\n"));
    QCOMPARE(gantry.joints.size(), std::size_t(4));
    QCOMPARE(gantry.joints[1].axis, 1);
    QCOMPARE(gantry.joints[2].axis, 1);
    QCOMPARE(gantry.joints[3].axis, 2);
  }

  // ---------------------------------------------------------------- jogging
  void jog_continuous_starts_and_stops_the_same_target() {
    std::vector<ipc::Command> out;
    JogController jog([&](const ipc::Command& c) { out.push_back(c); });
    jog.set_axes({{0, false, 0}, {1, false, 1}, {2, false, 2}});
    jog.set_linear_velocity(12.5);
    jog.update(on_status(true));
    QVERIFY(jog.press(0, -1, JogController::Source::Key));
    QCOMPARE(out.size(), std::size_t(1));
    QCOMPARE(out[0].type, CommandType::JogCont);
    QCOMPARE(out[0].i[0], 0);
    QCOMPARE(out[0].i[1], 0);  // homed: axis (teleop) jog
    QCOMPARE(out[0].d[0], -12.5);
    QVERIFY(!jog.press(0, -1, JogController::Source::Button));  // already moving
    jog.release(0, JogController::Source::Key);
    QCOMPARE(out.size(), std::size_t(2));
    QCOMPARE(out[1].type, CommandType::JogStop);
    QCOMPARE(out[1].i[0], 0);
    QCOMPARE(out[1].i[1], 0);
  }
  void jog_increment_and_joint_mode_before_homing() {
    std::vector<ipc::Command> out;
    JogController jog([&](const ipc::Command& c) { out.push_back(c); });
    jog.set_axes({{0, false, 0}, {1, false, 1}, {2, false, 2}});
    jog.set_increments({Increment{true, 0, "continuous"}, Increment{false, 0.1, "0.1 mm"}}, {});
    jog.set_linear_velocity(5);
    ipc::Status s = on_status(false);
    s.joints[2].axis = 2;
    jog.update(s);
    jog.select_increment(1);
    QVERIFY(jog.press(2, -1, JogController::Source::Button));
    QCOMPARE(out.back().type, CommandType::JogIncr);
    QCOMPARE(out.back().i[0], 2);
    QCOMPARE(out.back().i[1], 1);  // not homed: the joint
    QCOMPARE(out.back().d[0], 5.0);
    QCOMPARE(out.back().d[1], -0.1);
    jog.release(2, JogController::Source::Button);
    QCOMPARE(out.size(), std::size_t(1));  // an increment runs to its end
  }
  void jog_keys_are_off_while_a_text_field_has_focus() {
    std::vector<ipc::Command> out;
    JogController jog([&](const ipc::Command& c) { out.push_back(c); });
    jog.set_axes({{0, false, 0}});
    jog.update(on_status(true));
    QVERIFY(jog.press(0, 1, JogController::Source::Key));
    jog.set_text_input_focus(true);  // the held key's release will go to the text field
    QCOMPARE(out.size(), std::size_t(2));
    QCOMPARE(out[1].type, CommandType::JogStop);
    QVERIFY(!jog.keyboard_enabled());
    QVERIFY(!jog.press(0, 1, JogController::Source::Key));
    QCOMPARE(out.size(), std::size_t(2));
    QVERIFY(jog.press(0, 1, JogController::Source::Button));  // buttons still work
    jog.set_text_input_focus(false);
    QVERIFY(jog.keyboard_enabled());
  }
  void jog_stops_on_mode_state_increment_and_focus_changes() {
    std::vector<ipc::Command> out;
    JogController jog([&](const ipc::Command& c) { out.push_back(c); });
    jog.set_axes({{0, false, 0}, {1, false, 1}});
    jog.set_increments({Increment{true, 0, "continuous"}, Increment{false, 1, "1 mm"}}, {});
    const auto count_stops = [&]() {
      return std::count_if(out.begin(), out.end(), [](const ipc::Command& c) { return c.type == CommandType::JogStop; });
    };
    ipc::Status s = on_status(true);
    jog.update(s);
    jog.press(0, 1, JogController::Source::Button);
    jog.press(1, 1, JogController::Source::Key);
    s.task.mode = ipc::TaskMode::Mdi;
    jog.update(s);  // mode change: both stop
    QCOMPARE(count_stops(), 2);
    QVERIFY(!jog.press(0, 1, JogController::Source::Button));
    QCOMPARE(jog.why_not(), std::string("jogging needs MANUAL mode"));
    s.task.mode = ipc::TaskMode::Manual;
    jog.update(s);
    jog.press(0, 1, JogController::Source::Button);
    jog.select_increment(1);  // increment change
    QCOMPARE(count_stops(), 3);
    jog.press(0, 1, JogController::Source::Button);
    jog.focus_lost();
    QCOMPARE(count_stops(), 4);
    jog.press(0, 1, JogController::Source::Button);
    s.task.state = ipc::TaskState::Estop;
    jog.update(s);
    QCOMPARE(count_stops(), 5);
    QVERIFY(!jog.press(0, 1, JogController::Source::Button));
  }
  void jog_refuses_coupled_axes_before_homing_and_uses_angular_settings() {
    std::vector<ipc::Command> out;
    JogController jog([&](const ipc::Command& c) { out.push_back(c); });
    jog.set_axes({{1, false, -1}, {3, true, 3}});
    jog.set_increments({Increment{true, 0, "c"}}, {Increment{true, 0, "c"}, Increment{false, 15, "15"}});
    jog.set_angular_velocity(30);
    ipc::Status s = on_status(false);
    s.motion.joints = 4;
    s.joints[0].axis = 1;
    s.joints[1].axis = 1;  // gantry Y
    s.joints[2].axis = 2;
    s.joints[3].axis = 3;
    jog.update(s);
    QVERIFY(!jog.press(1, 1, JogController::Source::Button));
    QVERIFY(QString::fromStdString(jog.why_not()).contains("several joints"));
    jog.select_angular_increment(1);
    QVERIFY(jog.press(3, -1, JogController::Source::Button));
    QCOMPARE(out.back().type, CommandType::JogIncr);
    QCOMPARE(out.back().i[0], 3);
    QCOMPARE(out.back().d[0], 30.0);
    QCOMPARE(out.back().d[1], -15.0);
  }

  // ---------------------------------------------------------------- MDI history
  void mdi_history_dedupes_and_persists() {
    QTemporaryDir dir;
    const std::filesystem::path file = dir.path().toStdString() + "/sub/history.txt";
    {
      MdiHistory h(file);
      QVERIFY(h.load());
      QVERIFY(h.entries().empty());
      QVERIFY(h.add("G0 X1"));
      QVERIFY(h.add("  M3 S100 "));
      QVERIFY(h.add("g0x1"));  // same command: moves to the end, newest spelling kept
      QVERIFY(h.add("(msg, Hello World) G0 X1"));
      QVERIFY(h.add("(MSG, hello world) G0 X1"));  // comments differ in case: different
      QCOMPARE(h.entries(), (std::vector<std::string>{"M3 S100", "g0x1", "(msg, Hello World) G0 X1", "(MSG, hello world) G0 X1"}));
    }
    MdiHistory again(file);
    QVERIFY(again.load());
    QCOMPARE(again.entries().size(), std::size_t(4));
    QCOMPARE(again.entries()[1], std::string("g0x1"));
    // Only the file itself is in the folder: the write was atomic (no temporary left).
    std::size_t files = 0;
    for (const auto& e : std::filesystem::directory_iterator(file.parent_path())) files += e.is_regular_file() ? 1 : 0;
    QCOMPARE(files, std::size_t(1));
    QVERIFY(again.clear());
    QCOMPARE(read_file(file), std::string());
  }
  void mdi_history_is_bounded_and_reports_write_errors() {
    QTemporaryDir dir;
    MdiHistory h(dir.path().toStdString() + "/h.txt", 3);
    for (int i = 0; i < 5; ++i) h.add("G0 X" + std::to_string(i));
    QCOMPARE(h.entries(), (std::vector<std::string>{"G0 X2", "G0 X3", "G0 X4"}));
    MdiHistory bad("/proc/cannot/write/here");
    QVERIFY(!bad.add("G0"));
    QVERIFY(!bad.error().empty());
    QCOMPARE(bad.entries().size(), std::size_t(1));
  }

  // ---------------------------------------------------------------- alarms
  void alarms_need_acknowledging_and_repeats_are_kept() {
    AlarmLog log;
    std::vector<LogEntry> seen;
    log.on_log = [&](const LogEntry& e) { seen.push_back(e); };
    Message m;
    m.kind = MessageKind::Error;
    m.source.assign("motion");
    m.text.assign("joint 0 following error");
    m.time_ns = 1000;
    log.post(m);
    log.post(m);
    m.kind = MessageKind::Text;
    m.text.assign("homing finished");
    log.post(m);
    QCOMPARE(log.active_count(), std::size_t(2));
    QCOMPARE(log.log().size(), std::size_t(3));
    QCOMPARE(seen.size(), std::size_t(3));
    const uint64_t first = log.active()[0]->id;
    QVERIFY(log.acknowledge(first, 2000));
    QVERIFY(!log.acknowledge(first, 2000));
    QCOMPARE(log.active_count(), std::size_t(1));
    QCOMPARE(log.acknowledge_all(3000), 1);
    QCOMPARE(log.active_count(), std::size_t(0));
    QCOMPARE(log.alarms().size(), std::size_t(2));  // kept, acknowledged
    QVERIFY(log.alarms()[0].acknowledged && log.alarms()[0].acknowledged_ns == 2000);
  }
  void alarms_decode_drive_faults_with_the_drive_named() {
    AlarmLog log;
    ipc::Status s{};
    s.drives[1].present = true;
    s.drives[1].joint = 1;
    s.drives[1].name.assign("y-drive");
    s.drives[1].state = kDriveStateFault;
    s.drives[1].error_code = 0x2310;
    log.update_drives(s, 5);
    QCOMPARE(log.active_count(), std::size_t(1));
    const std::string text = log.active()[0]->text;
    QVERIFY(text.find("y-drive (joint 1)") != std::string::npos);
    QVERIFY(text.find("0x2310") != std::string::npos);
    QVERIFY(text.find("continuous over-current") != std::string::npos);
    log.update_drives(s, 6);  // same fault: no new alarm
    QCOMPARE(log.alarms().size(), std::size_t(1));
    s.drives[1].error_code = 0x8611;
    log.update_drives(s, 7);  // another code: a new alarm
    QCOMPARE(log.alarms().size(), std::size_t(2));
    QVERIFY(log.alarms()[1].text.find("following error") != std::string::npos);
    s.drives[1].state = 4;
    log.update_drives(s, 8);
    QVERIFY(log.log().back().text.find("fault cleared") != std::string::npos);
    QCOMPARE(decode_drive_error(0x2399), std::string("current, device output side"));
    QCOMPARE(decode_drive_error(0x5530), std::string("data storage (EEPROM)"));
    QCOMPARE(std::string(drive_state_name(4)), std::string("operation enabled"));
  }

  void alarms_of_a_controller_that_keeps_them_are_its_table_not_the_messages() {
    // A screen started after two alarms, one acknowledged by another screen:
    // only the active one shows, with its count.
    ipc::AlarmStatus a;
    a.available = true;
    a.revision = 3;
    a.list[0].id = 4;
    a.list[0].count = 1;
    a.list[0].acknowledged = true;
    a.list[0].text.assign("old, acknowledged");
    a.list[1].id = 5;
    a.list[1].count = 3;
    a.list[1].source.assign("task");
    a.list[1].text.assign("program aborted at line 3: joint 1 amplifier fault; drive y: over-current");
    AlarmLog log;
    std::vector<uint32_t> sent;
    log.acknowledge_in_controller = [&](uint32_t id) { sent.push_back(id); };
    log.update_controller(a);
    QVERIFY(log.controller_keeps_alarms());
    QCOMPARE(log.active_count(), std::size_t(1));
    QCOMPARE(log.active()[0]->count, 3u);
    // Messages and drive faults are logged, not raised again here.
    Message m;
    m.kind = MessageKind::Error;
    m.source.assign("motion");
    m.text.assign("joint 1 amplifier fault");
    log.post(m);
    ipc::Status s{};
    s.drives[1].present = true;
    s.drives[1].joint = 1;
    s.drives[1].state = kDriveStateFault;
    s.drives[1].error_code = 0x2310;
    log.update_drives(s, 5);
    QCOMPARE(log.active_count(), std::size_t(1));
    QCOMPARE(log.log().size(), std::size_t(2));
    // Acknowledging asks the controller; the alarm goes when its status says so.
    QVERIFY(log.acknowledge(log.active()[0]->id, 10));
    QCOMPARE(sent, std::vector<uint32_t>{5});
    QCOMPARE(log.active_count(), std::size_t(1));
    a.list[1].acknowledged = true;
    a.revision = 4;
    log.update_controller(a);
    QCOMPARE(log.active_count(), std::size_t(0));
    // The screen's own errors stay local alarms.
    log.post_local(LogLevel::Error, "screen", "command refused", 11);
    QCOMPARE(log.active_count(), std::size_t(1));
    QCOMPARE(log.acknowledge_all(12), 1);
    QCOMPARE(sent.size(), std::size_t(1));  // nothing of the controller's was active
  }

  void trends_keep_the_window_and_restart_when_time_goes_back() {
    Trend t(10.0, 100);
    for (int i = 0; i <= 20; ++i) t.add(i, i * 0.5);
    QCOMPARE(t.points().size(), std::size_t(11));  // 10..20 s
    QCOMPARE(t.points().front().first, 10.0);
    QCOMPARE(t.range(), std::make_pair(5.0, 10.0));
    Trend few(100.0, 3);
    for (int i = 0; i < 5; ++i) few.add(i, -i);
    QCOMPARE(few.points().size(), std::size_t(3));
    QCOMPARE(few.range(), std::make_pair(-4.0, -2.0));
    few.add(1.0, 7);  // a new clock
    QCOMPARE(few.points().size(), std::size_t(1));
  }

  // ---------------------------------------------------------------- positions
  // ---------------------------------------------------------------- readouts
  void readout_feed_after_estop_shows_no_programmed_feed_and_zero_speed() {
    ipc::Status s = on_status(true, ipc::TaskMode::Auto);
    s.task.active_settings[1] = 1200;
    s.motion.current_vel = 20;  // 1200 mm/min
    s.motion.enabled = true;
    QCOMPARE(feed_readout(s, false), std::string("F 1200 mm/min × 100% = 1200 mm/min · now 1200 mm/min"));
    s.task.state = ipc::TaskState::Estop;
    s.motion.enabled = false;
    QCOMPARE(feed_readout(s, false), std::string("F – (machine off) · now 0 mm/min"));
  }
  void readout_spindle_shows_commanded_and_actual_apart() {
    ipc::Status s = on_status(true, ipc::TaskMode::Auto);
    s.task.active_settings[2] = 3000;
    auto& sp = s.spindles[0];
    sp.enabled = true;
    sp.direction = 1;
    sp.speed_out = 3000;
    sp.override_scale = 1;
    sp.speed_feedback = 500;
    sp.at_speed = false;
    QCOMPARE(spindle_readout(s), std::string("S 3000 rpm × 100% = 3000 rpm FWD · actual 500 rpm · NOT AT SPEED"));
    sp.enabled = false;
    sp.speed_feedback = 0;
    QCOMPARE(spindle_readout(s), std::string("S 3000 rpm · spindle stopped · actual 0 rpm"));
  }
  void readout_mdi_running_only_while_a_line_runs() {
    ipc::Status s = on_status(true, ipc::TaskMode::Mdi);
    s.task.command.assign("G0 X1000");
    s.task.interp_state = ipc::InterpState::Reading;
    QCOMPARE(mdi_running_readout(s), std::string("running: G0 X1000"));
    // Rejected: the task went idle (an old controller left the text).
    s.task.interp_state = ipc::InterpState::Idle;
    QCOMPARE(mdi_running_readout(s), std::string());
  }
  void readout_progress_percent_estimate_and_errors_only_of_a_program() {
    ipc::Status s = on_status(true, ipc::TaskMode::Auto);
    s.task.file.assign("/tmp/p.ngc");
    s.task.total_lines = 400;
    s.task.errors_since_start = 1;  // an MDI error before any program
    QCOMPARE(progress_readout(s), std::string("line 0 of 400 · 0%"));
    s.task.interp_state = ipc::InterpState::Reading;
    s.task.current_line = 100;
    s.task.program_started_ns = 1;
    s.task.errors_since_start = 0;
    s.task.program_elapsed_ns = 60'000'000'000;
    const ProgramProgress p = program_progress(s);
    QCOMPARE(p.percent, 25);
    QCOMPARE(p.remaining_s, 180.0);
    QCOMPARE(progress_readout(s), std::string("line 100 of 400 · 25% · 0:01:00 · about 0:03:00 left (from lines)"));
    s.task.errors_since_start = 2;
    QVERIFY(progress_readout(s).find("errors: 2") != std::string::npos);
  }
  void readout_progress_with_the_planners_estimate() {
    ipc::Status s = on_status(true, ipc::TaskMode::Auto);
    s.task.file.assign("/tmp/p.ngc");
    s.task.total_lines = 400;
    // before the run: the planned motion time
    QCOMPARE(progress_readout(s, 233.4), std::string("line 0 of 400 · 0% · planned 0:03:53 of motion"));
    // while it runs: the estimate less the time run so far, not the lines
    s.task.interp_state = ipc::InterpState::Reading;
    s.task.current_line = 100;
    s.task.program_started_ns = 1;
    s.task.program_elapsed_ns = 60'000'000'000;
    QCOMPARE(progress_readout(s, 233.4), std::string("line 100 of 400 · 25% · 0:01:00 · about 0:02:53 left (planner)"));
    // a run longer than the estimate (tool changes, waits): nothing left, not negative
    s.task.program_elapsed_ns = 300'000'000'000;
    QVERIFY(progress_readout(s, 233.4).find("about 0:00:00 left (planner)") != std::string::npos);
  }
  void parse_estimate_reads_cnc_estimates_motion_time() {
    const auto v = parse_estimate_output(
        "configs/sim/nc_files/demo.ngc: 66.319 s of motion (1:06.319), 63 moves, 4 stops\nend position X180 Y110 Z0\n");
    QVERIFY(v.has_value());
    QCOMPARE(*v, 66.319);
    QVERIFY(!parse_estimate_output("cnc-estimate: demo.ngc:3: Unknown g code used\n").has_value());
    QVERIFY(!parse_estimate_output("").has_value());
  }
  void readout_statusword_names_the_cia402_bits() {
    // Operation enabled: 0x0237 = ready, switched on, enabled, voltage, quick stop off, remote.
    QCOMPARE(statusword_readout(0x1637),
             std::string("0x1637: ready to switch on, switched on, operation enabled, voltage enabled, remote, "
                         "target reached, set-point followed"));
    const auto fault = statusword_bits(0x2008 | 0x0003);
    QVERIFY(std::find(fault.begin(), fault.end(), "fault") != fault.end());
    QVERIFY(std::find(fault.begin(), fault.end(), "following error") != fault.end());
    QVERIFY(std::find(fault.begin(), fault.end(), "QUICK STOP active") != fault.end());
    QCOMPARE(statusword_short(0x1637), std::string("0x1637 RTSO SO OE VE RM TR SPF"));
    QCOMPARE(statusword_short(0x200B), std::string("0x200B RTSO SO F QS! FE"));
  }
  void readout_drive_units() {
    QCOMPARE(drive_velocity_unit(false, false, false), std::string("mm/s"));
    QCOMPARE(drive_velocity_unit(true, false, false), std::string("rpm"));
    QCOMPARE(drive_position_unit(true, false), std::string("°"));
    ipc::DriveStatus d;
    d.joint = -1;
    d.velocity = 10;
    QCOMPARE(drive_velocity_value(d), 600.0);
  }

  void positions_follow_the_task_conversion() {
    ipc::Status s{};
    s.motion.linear_units = 1;
    s.task.program_units = 2;
    s.task.g5x_offset[0] = 100;
    s.task.g5x_offset[1] = 50;
    s.task.g92_offset[0] = 5;
    s.task.tool_offset[2] = 35;
    s.motion.position[0] = 110;
    s.motion.position[1] = 60;
    s.motion.position[2] = 0;
    s.motion.dtg[0] = 2;
    DroPositions d = dro_positions(s, false);
    QCOMPARE(d.work[0], 5.0);   // 110 - 100 - 5
    QCOMPARE(d.work[1], 10.0);
    QCOMPARE(d.work[2], -35.0);
    QCOMPARE(d.dtg[0], 2.0);
    // 90 degrees rotation: machine +Y is program +X.
    s.task.g92_offset = Pose{};
    s.task.rotation_xy = 90;
    d = dro_positions(s, false);
    QVERIFY(std::fabs(d.work[0] - 10) < 1e-9);
    QVERIFY(std::fabs(d.work[1] + 10) < 1e-9);
    // Inch program on a mm machine.
    s.task.rotation_xy = 0;
    s.task.program_units = 1;
    s.task.g5x_offset = Pose{};
    s.task.tool_offset = Pose{};
    s.motion.position[0] = 25.4;
    QCOMPARE(dro_positions(s, false).work[0], 1.0);
    // Actual position unknown before homing.
    s.motion.carte_fb_valid = false;
    QVERIFY(!dro_positions(s, true).valid);
  }
  void touch_off_makes_the_axis_read_the_value() {
    ipc::Status s{};
    s.motion.linear_units = 1;
    s.task.program_units = 2;
    s.task.g5x_offset[0] = 12;
    s.task.g5x_offset[1] = -3;
    s.task.g92_offset[1] = 2;
    s.task.tool_offset[2] = 20;
    s.task.rotation_xy = 30;
    s.motion.position[0] = 77;
    s.motion.position[1] = 41;
    s.motion.position[2] = -5;
    const DroPositions before = dro_positions(s, false);
    for (int axis : {0, 1, 2}) {
      ipc::Status t = s;
      t.task.g5x_offset = touch_off_offsets(s, axis, 1.25, false);
      const DroPositions after = dro_positions(t, false);
      for (int a = 0; a < 3; ++a) {
        const double want = a == axis ? 1.25 : before.work[a];
        QVERIFY2(std::fabs(after.work[a] - want) < 1e-9, qPrintable(QString("axis %1 a %2").arg(axis).arg(a)));
      }
    }
  }
  void parameter_file_gives_the_work_offsets() {
    const auto w = work_offsets_from_parameters(parse_parameter_text("5211 1.5\n5220 2.000000\n5221 10\n5222 20\n"
                                                                     "5230 45\n5241 -7\n5389 3\n junk line\n"));
    QCOMPARE(w.g92[0], 1.5);
    QCOMPARE(w.active, 2);
    QCOMPARE(w.g5x[0][0], 10.0);
    QCOMPARE(w.g5x[0][1], 20.0);
    QCOMPARE(w.rotation[0], 45.0);
    QCOMPARE(w.g5x[1][0], -7.0);
    QCOMPARE(w.g5x[8][8], 3.0);  // G59.3 W (5381 + 8)
    QCOMPARE(work_offset_name(9), std::string("G59.3"));
    QVERIFY(!read_work_offsets("/nonexistent/file.var").error.empty());
    ipc::Status s{};
    s.task.active_gcodes[3] = 70;
    QVERIFY(diameter_mode(s));
  }

  // ---------------------------------------------------------------- commands
  void commands_carry_the_documented_arguments() {
    QCOMPARE(commands::mdi("G0 X1").i[0], -1);
    QCOMPARE(std::string(commands::mdi("G0 X1").text.view()), std::string("G0 X1"));
    QCOMPARE(commands::macro(2).i[0], 2);
    QCOMPARE(commands::set_mode(ipc::TaskMode::Auto).i[0], 2);
    QCOMPARE(commands::home(-1).i[0], -1);
    QCOMPARE(commands::feed_override(1.2).d[0], 1.2);
    QCOMPARE(commands::spindle_on(-800).d[0], -800.0);
    tooltable::Tool t;
    t.number = 7;
    t.pocket = 3;
    t.offset[2] = 41.5;
    t.diameter = 8;
    t.comment = "drill";
    const auto c = commands::tool_set(t, false);
    QCOMPARE(c.type, CommandType::ToolSetOffset);
    QCOMPARE(c.i[0], 7);
    QCOMPARE(c.i[1], -1);
    QCOMPARE(c.d[2], 41.5);
    QCOMPARE(c.d[9], 8.0);
    QCOMPARE(std::string(c.text.view()), std::string("drill"));
    Pose p;
    p[0] = 3;
    const auto w = commands::set_work_offset(2, p, 15);
    QCOMPARE(w.i[0], 2);
    QCOMPARE(w.d[0], 3.0);
    QCOMPARE(w.d[9], 15.0);
  }
  void tracker_follows_answers_and_sequences() {
    FakeLink link;
    CommandTracker tracker(link);
    std::vector<std::string> rejected;
    tracker.set_reject_sink([&](const std::string& what, const std::string& why) { rejected.push_back(what + ": " + why); });
    link.default_answer = ipc::CommandState::Executing;
    ipc::CommandResult last;
    QVERIFY(tracker.send_sequence({commands::set_mode(ipc::TaskMode::Mdi), commands::mdi("G0 X1")}, "mdi",
                                  [&](const ipc::CommandResult& r) { last = r; }));
    QCOMPARE(link.sent.size(), std::size_t(1));
    tracker.poll(1);
    QCOMPARE(link.sent.size(), std::size_t(1));  // the mode change is still executing
    link.answer(link.sent[0].serial, ipc::CommandState::Done);
    tracker.poll(2);
    QCOMPARE(link.sent.size(), std::size_t(2));
    QCOMPARE(link.sent[1].type, CommandType::TaskPlanExecute);
    QCOMPARE(last.state, ipc::CommandState::None);
    link.answer(link.sent[1].serial, ipc::CommandState::Rejected, "line 1: bad");
    tracker.poll(3);
    QCOMPARE(last.state, ipc::CommandState::Rejected);
    QCOMPARE(rejected.size(), std::size_t(1));
    QVERIFY(rejected[0].find("line 1: bad") != std::string::npos);
    QCOMPARE(tracker.pending(), std::size_t(0));
    // A rejection in the middle stops the sequence.
    link.clear_sent();
    link.answers[CommandType::TaskSetMode] = {ipc::CommandState::Rejected, "not on"};
    tracker.send_sequence({commands::set_mode(ipc::TaskMode::Auto), commands::run(0)}, "run");
    tracker.poll(4);
    tracker.poll(5);
    QCOMPARE(link.sent.size(), std::size_t(1));
    // Not sent at all, and no answer ever.
    link.accept_sends = false;
    ipc::CommandState st = ipc::CommandState::None;
    QVERIFY(!tracker.send(commands::abort(), "abort", [&](const ipc::CommandResult& r) { st = r.state; }));
    QCOMPARE(st, ipc::CommandState::Rejected);
    link.accept_sends = true;
    link.default_answer = ipc::CommandState::None;
    link.answers.clear();
    tracker.poll(10);
    tracker.send(commands::pause(), "pause", [&](const ipc::CommandResult& r) { st = r.state; });
    st = ipc::CommandState::None;
    tracker.poll(10 + CommandTracker::kNoAnswerNs / 2);
    QCOMPARE(st, ipc::CommandState::None);
    tracker.poll(20 + CommandTracker::kNoAnswerNs);
    QCOMPARE(st, ipc::CommandState::Rejected);
  }

  // ---------------------------------------------------------------- preview
  void preview_follows_offsets_arcs_and_checks_limits() {
    QTemporaryDir dir;
    write(dir, "sim.var", "5220 1\n5221 100\n5222 50\n5223 -80\n");
    write(dir, "tool.tbl", "T1 P1 D6 Z+35 ;mill\n");
    const std::string ini = write(dir, "m.ini",
                                  "[RS274NGC]\nPARAMETER_FILE = sim.var\n[EMCIO]\nTOOL_TABLE = tool.tbl\n"
                                  "[TRAJ]\nCOORDINATES = XYZ\nLINEAR_UNITS = mm\n");
    const std::string prog = write(dir, "p.ngc",
                                   "G21 G90 G17\n"           // 1
                                   "G0 X0 Y0 Z5\n"           // 2
                                   "G1 Z-1 F100\n"           // 3
                                   "G2 X20 Y0 I10 J0\n"      // 4 half circle, radius 10, centre X10
                                   "G1 X250\n"               // 5 machine X 350: beyond 300
                                   "M2\n");
    PreviewInput in;
    in.program = prog;
    in.ini = ini;
    in.limits = {{0, -1, 300}, {1, -1, 200}, {2, -120, 1}};
    const PreviewResult r = build_preview(in);
    QVERIFY2(r.error.empty(), r.error.c_str());
    QVERIFY(r.points.size() > 10);
    QCOMPARE(r.points.front().kind, MoveKind::Start);
    QCOMPARE(r.points[1].kind, MoveKind::Rapid);
    QCOMPARE(r.points[1].x, 100.0f);  // G54 X100 from the parameter file
    QCOMPARE(r.points[1].y, 50.0f);
    QCOMPARE(r.points[1].z, -75.0f);
    // Every arc point is 10 from the centre (110, 50); clockwise from X100 it passes over +Y.
    float max_y = -1e9f;
    for (const auto& p : r.points) {
      if (p.kind != MoveKind::Arc) continue;
      QCOMPARE(p.line, 4);
      QVERIFY(std::fabs(std::hypot(p.x - 110.0, p.y - 50.0) - 10.0) < 1e-3);
      max_y = std::max(max_y, p.y);
    }
    QVERIFY(std::fabs(max_y - 60.0f) < 0.01);
    QCOMPARE(r.max[0], 350.0);
    QCOMPARE(r.violations.size(), std::size_t(1));
    QCOMPARE(r.violations[0].axis, 0);
    QVERIFY(r.violations[0].above);
    QCOMPARE(r.violations[0].first_line, 5);
    QCOMPARE(r.violations[0].value, 350.0);
    // The controller's parameter file is untouched.
    QCOMPARE(read_file(dir.path().toStdString() + "/sim.var"), std::string("5220 1\n5221 100\n5222 50\n5223 -80\n"));
  }
  void preview_reports_errors_and_can_be_cancelled() {
    QTemporaryDir dir;
    const std::string prog = write(dir, "bad.ngc", "G0 X1\nG1 X2 F100\nG2 X3\nM2\n");  // arc without centre
    PreviewInput in;
    in.program = prog;
    PreviewResult r = build_preview(in);
    QVERIFY(!r.error.empty());
    QCOMPARE(r.error_line, 3);
    QVERIFY(r.points.size() >= 3);  // the path up to the error
    std::atomic<bool> cancel{true};
    r = build_preview(in, &cancel);
    QVERIFY(r.cancelled);
    // Points inside the limits: no violation (a point exactly on a limit counts as inside).
    std::vector<PathPoint> pts = {{0, 0, 0, 0, MoveKind::Start}, {300, 0, 0, 1, MoveKind::Feed}};
    QVERIFY(check_limits(pts, {{0, -1, 300}}).empty());
    pts.push_back({-1.5f, 0, 0, 2, MoveKind::Rapid});
    const auto v = check_limits(pts, {{0, -1, 300}});
    QCOMPARE(v.size(), std::size_t(1));
    QVERIFY(!v[0].above);
    QCOMPARE(v[0].first_line, 2);
  }

  // ---------------------------------------------------------------- user dialogs
  void user_dialogs_read_the_manual_examples() {
    const auto c = UserDialogConfig::from_ini(ini::IniFile::parse(
        "[DISPLAY]\n"
        "MESSAGE_BOLDTEXT = This is an information message\nMESSAGE_TEXT = This is low priority\n"
        "MESSAGE_DETAILS = press ok to clear\nMESSAGE_TYPE = okdialog status\nMESSAGE_PINNAME = bothtest\nMESSAGE_ICON = INFO\n"
        "MESSAGE_TEXT = Door open?\nMESSAGE_TYPE = yesnodialog\nMESSAGE_PINNAME = Door_Check\n"
        "MULTIMESSAGE_ID = VFD\n"
        "MULTIMESSAGE_VFD_NUMBER = 1\nMULTIMESSAGE_VFD_TYPE = okdialog status\nMULTIMESSAGE_VFD_TITLE = VFD Error: 1\n"
        "MULTIMESSAGE_VFD_TEXT = This is the longer text FOR MESSAGE NUMBER 1\n"
        "MULTIMESSAGE_VFD_DETAILS = DETAILS for VFD error 1\nMULTIMESSAGE_VFD_DETAILS = DETAILS for VFD error 1\n"
        "MULTIMESSAGE_VFD_ICON = WARNING\n"
        "MULTIMESSAGE_VFD_NUMBER = 2\nMULTIMESSAGE_VFD_TYPE = nonedialog status\nMULTIMESSAGE_VFD_TITLE = VFD Error: 2\n"
        "MULTIMESSAGE_VFD_NUMBER = 3\nMULTIMESSAGE_VFD_TYPE = status\nMULTIMESSAGE_VFD_TEXT = three\n"));
    QCOMPARE(c.messages.size(), std::size_t(2));
    QCOMPARE(c.messages[0].pin, std::string("bothtest"));
    QVERIFY(c.messages[0].ok && c.messages[0].status && !c.messages[0].yesno);
    QCOMPARE(c.messages[0].title, std::string("This is an information message"));
    QCOMPARE(c.messages[1].pin, std::string("door-check"));
    QVERIFY(c.messages[1].yesno);
    QCOMPARE(c.multi.size(), std::size_t(1));
    QCOMPARE(c.multi[0].pin, std::string("vfd"));
    QCOMPARE(c.multi[0].messages.size(), std::size_t(3));
    QCOMPARE(c.multi[0].find(1)->details, std::string("DETAILS for VFD error 1"));
    QCOMPARE(c.multi[0].find(1)->icon, std::string("WARNING"));  // the repeated DETAILS did not shift the rest
    QVERIFY(c.multi[0].find(2)->none);
    QVERIFY(c.multi[0].find(3)->status && !c.multi[0].find(3)->has_dialog());
    UserDialogLogic logic(c);
    const auto setup = logic.setup_commands();
    QCOMPARE(setup.front(), std::string("newcomp hmi"));
    QVERIFY(std::find(setup.begin(), setup.end(), "newpin hmi hmi.bothtest bit io") != setup.end());
    QVERIFY(std::find(setup.begin(), setup.end(), "newpin hmi hmi.door-check-response bit out") != setup.end());
    QVERIFY(std::find(setup.begin(), setup.end(), "newpin hmi hmi.vfd s32 io") != setup.end());
    QVERIFY(std::find(setup.begin(), setup.end(), "newpin hmi hmi.vfd-waiting bit out") != setup.end());
    std::string why;
    QVERIFY(hal_pin_word("bad name!", &why).empty());
    QVERIFY(!why.empty());
  }
  void user_dialogs_follow_the_pins() {
    const auto c = UserDialogConfig::from_ini(ini::IniFile::parse(
        "[DISPLAY]\nMESSAGE_TEXT = ok?\nMESSAGE_TYPE = okdialog\nMESSAGE_PINNAME = a\n"
        "MESSAGE_TEXT = yes?\nMESSAGE_TYPE = yesnodialog\nMESSAGE_PINNAME = b\n"
        "MESSAGE_TEXT = wait\nMESSAGE_TYPE = nonedialog\nMESSAGE_PINNAME = c\n"
        "MULTIMESSAGE_ID = vfd\nMULTIMESSAGE_vfd_NUMBER = 4\nMULTIMESSAGE_vfd_TEXT = four\n"));
    UserDialogLogic logic(c);
    using K = UserDialogLogic::Action::Kind;
    const auto has = [](const std::vector<UserDialogLogic::Action>& acts, K k, const std::string& pin = {},
                        const std::string& value = {}) {
      return std::any_of(acts.begin(), acts.end(), [&](const auto& a) {
        return a.kind == k && (pin.empty() || a.pin == pin) && (value.empty() || a.value == value);
      });
    };
    auto pins = parse_show_pin(
        "Component Pins:\nOwner         Type  Dir         Value  Name\n"
        "hmi           bit   I/O           TRUE  hmi.a\nhmi           bit   I/O          FALSE  hmi.b <=> door\n"
        "hmi           bit   I/O          FALSE  hmi.c\nhmi           s32   I/O              0  hmi.vfd\n");
    QCOMPARE(pins["hmi.a"], std::string("TRUE"));
    QCOMPARE(pins["hmi.b"], std::string("FALSE"));
    auto acts = logic.update(pins);
    QVERIFY(has(acts, K::Show));
    QVERIFY(has(acts, K::Set, "hmi.a-waiting", "TRUE"));
    QVERIFY(logic.update(pins).empty());  // still TRUE: shown once
    const UserMessage* a = &logic.config().messages[0];
    acts = logic.answer(a, true);
    QVERIFY(has(acts, K::Close));
    QVERIFY(has(acts, K::Set, "hmi.a", "FALSE"));
    QVERIFY(has(acts, K::Set, "hmi.a-waiting", "FALSE"));
    QVERIFY(logic.update(pins).empty());  // a late poll still showing TRUE does not pop it again
    pins["hmi.a"] = "FALSE";
    QVERIFY(logic.update(pins).empty());
    pins["hmi.a"] = "TRUE";
    QVERIFY(has(logic.update(pins), K::Show));  // a new rising edge does
    // yes/no answers on the response pin.
    pins["hmi.b"] = "TRUE";
    logic.update(pins);
    acts = logic.answer(&logic.config().messages[1], false);
    QVERIFY(has(acts, K::Set, "hmi.b-response", "FALSE"));
    // nonedialog: closes when HAL resets the pin.
    pins["hmi.c"] = "TRUE";
    QVERIFY(has(logic.update(pins), K::Show));
    pins["hmi.c"] = "FALSE";
    acts = logic.update(pins);
    QVERIFY(has(acts, K::Close));
    QVERIFY(has(acts, K::Set, "hmi.c-waiting", "FALSE"));
    // Multi: a number shows its message; an unknown number is logged.
    pins["hmi.vfd"] = "4";
    QVERIFY(has(logic.update(pins), K::Show));
    pins["hmi.vfd"] = "5";
    acts = logic.update(pins);
    QVERIFY(has(acts, K::Close));
    QVERIFY(has(acts, K::Log));
  }
};

QTEST_GUILESS_MAIN(LogicTests)
#include "logic_tests.moc"
