// The screen's widgets against a fake controller (FakeLink: a status the
// test writes, a recording command sink) and a fake halcmd channel. Runs on
// Qt's offscreen platform: no display needed.
#include <QApplication>
#include <QDir>
#include <QFileInfo>
#include <QInputDialog>
#include <QCheckBox>
#include <QComboBox>
#include <QLabel>
#include <QtCharts/QChartView>
#include <QLineEdit>
#include <QListWidget>
#include <QMessageBox>
#include <QPushButton>
#include <QSlider>
#include <QTabWidget>
#include <QTableWidget>
#include <QTemporaryDir>
#include <QtTest>
#include <algorithm>
#include <fstream>
#include <mutex>

#include "core/ini/ini_file.hpp"
#include "core/util/atomic_file.hpp"
#include "fake_link.hpp"
#include "hmi/main_window.hpp"
#include "hmi/panels.hpp"
#include "hmi/preview_widget.hpp"
#include "hmi/program_text.hpp"

using namespace cnc;
using namespace cnc::hmi;
using cnc::hmi::testing::FakeLink;
using ipc::CommandType;

namespace {

const char* kIni = R"([EMC]
MACHINE = Test mill
[DISPLAY]
TITLE = Widget test mill
CYCLE_TIME = 0.1
INCREMENTS = 1 mm, 0.1 mm
DEFAULT_LINEAR_VELOCITY = 10
MAX_LINEAR_VELOCITY = 50
MAX_FEED_OVERRIDE = 1.5
MIN_SPINDLE_0_OVERRIDE = 0.5
MAX_SPINDLE_0_OVERRIDE = 1.2
MDI_HISTORY_FILE = mdi_history.txt
PROGRAM_PREFIX = .
[FILTER]
PROGRAM_EXTENSION = .ngc G-code
PROGRAM_EXTENSION = .txt Text through a filter
txt = sh filter.sh
[RS274NGC]
PARAMETER_FILE = sim.var
[EMCIO]
TOOL_TABLE = tool.tbl
[TRAJ]
COORDINATES = X Y Z
LINEAR_UNITS = mm
MAX_LINEAR_VELOCITY = 100
[KINS]
KINEMATICS = trivkins coordinates=XYZ
JOINTS = 3
[AXIS_X]
MIN_LIMIT = -1
MAX_LIMIT = 300
[AXIS_Y]
MIN_LIMIT = -1
MAX_LIMIT = 200
[AXIS_Z]
MIN_LIMIT = -120
MAX_LIMIT = 1
[HAL]
POSTGUI_HALFILE = post.hal
POSTGUI_HALCMD = echo after the postgui file
[MDI_COMMAND_LIST]
MDI_COMMAND_MACRO0 = G53 G0 Z0;G53 G0 X280 Y180, Park
MDI_COMMAND_MACRO1 = G10 L20 P1 X0 Y0, Zero XY\nhere
)";

QString screenshot_dir() {
  const QString d = QString(CNC_BINARY_DIR) + "/hmi-screenshots";
  QDir().mkpath(d);
  return d;
}

// A window on a fake controller, in a temporary configuration folder.
struct Rig {
  QTemporaryDir dir;
  FakeLink* link = nullptr;
  std::mutex hal_mutex;
  std::vector<std::string> hal_lines;
  std::string show_pin;
  // Answers to halcmd lines starting with the key (the scope's); ok = false
  // when the text starts with "ERROR ".
  std::vector<std::pair<std::string, std::string>> replies;
  std::unique_ptr<MainWindow> w;

  explicit Rig(const std::string& extra = {}, const std::string& base = kIni, MainWindow::Options opt = {},
               bool embed = false) {
    write("tool.tbl", "T1 P1 D6 Z+35 ;6 mm end mill\nT2 P2 D10 Z+42.5 ;10 mm end mill\n");
    write("sim.var", "5220 1\n5221 100\n5222 50\n5223 -80\n");
    write("post.hal", "echo postgui file\n");
    write("filter.sh", "echo FILTER_PROGRESS=50 >&2\necho 'G0 X1 Y2'\necho 'M2'\n");
    const std::string ini = write("test.ini", base + extra);
    const ini::IniFile file = ini::IniFile::load(ini);
    auto fake = std::make_unique<FakeLink>();
    link = fake.get();
    opt.start_timer = false;
    opt.embed_tabs = embed;
    HalExecutor hal = [this](const std::string& line) {
      std::lock_guard lock(hal_mutex);
      hal_lines.push_back(line);
      ipc::AdminReply r;
      if (line.rfind("show pin", 0) == 0) r.text = show_pin;
      for (const auto& [prefix, text] : replies) {
        if (line.rfind(prefix, 0) == 0) {
          r.ok = text.rfind("ERROR ", 0) != 0;
          r.text = r.ok ? text : text.substr(6);
        }
      }
      return r;
    };
    w = std::make_unique<MainWindow>(HmiConfig::from_ini(file), UserDialogConfig::from_ini(file), std::move(fake), hal, opt);
    w->resize(1280, 800);
    w->show();
  }
  std::string write(const std::string& name, const std::string& text) {
    const std::string p = dir.path().toStdString() + "/" + name;
    std::ofstream(p) << text;
    return p;
  }
  template <class T>
  T* find(const char* name) const {
    T* t = w->findChild<T*>(name);
    if (!t) qWarning("no widget named %s", name);
    return t;
  }
  void tick(int n = 1) {
    for (int i = 0; i < n; ++i) {
      w->tick();
      QCoreApplication::processEvents();
    }
  }
  std::vector<std::string> hal() {
    std::lock_guard lock(hal_mutex);
    return hal_lines;
  }
  void set_reply(const std::string& prefix, const std::string& text) {
    std::lock_guard lock(hal_mutex);
    replies.emplace_back(prefix, text);
  }
  void show(const char* page) {
    for (int i = 0; i < w->tabs()->count(); ++i) {
      if (w->tabs()->widget(i)->objectName() == page) w->tabs()->setCurrentIndex(i);
    }
  }
  std::vector<std::string> mdi_lines() const {
    std::vector<std::string> out;
    for (const auto& c : link->sent_of(CommandType::TaskPlanExecute)) out.emplace_back(c.text.view());
    return out;
  }
  void set_show_pin(const std::string& s) {
    std::lock_guard lock(hal_mutex);
    show_pin = s;
  }
};

QString text_of(QLabel* l) { return l ? l->text() : QString("<missing>"); }

bool contains(const std::vector<std::string>& lines, const std::string& line) {
  return std::find(lines.begin(), lines.end(), line) != lines.end();
}

}  // namespace

class WidgetTests : public QObject {
  Q_OBJECT
 private slots:
  void dro_shows_work_machine_and_distance_to_go() {
    Rig r;
    r.link->set_on();
    r.link->status.task.g5x_offset[0] = 100;
    r.link->status.task.g5x_offset[1] = 50;
    r.link->status.motion.position[0] = 110;
    r.link->status.motion.position[1] = 62.5;
    r.link->status.motion.dtg[0] = 3;
    r.tick();
    QCOMPARE(text_of(r.find<QLabel>("droWork_X")), QString("10.000"));
    QCOMPARE(text_of(r.find<QLabel>("droWork_Y")), QString("12.500"));
    QCOMPARE(text_of(r.find<QLabel>("droMachine_X")), QString("110.000"));
    QCOMPARE(text_of(r.find<QLabel>("droDtg_X")), QString("3.000"));
    QVERIFY(text_of(r.find<QLabel>("droMarks_X")).contains("●"));  // homed
    r.link->status.joints[0].homed = false;
    r.link->status.joints[0].max_hard_limit = true;
    r.tick();
    QVERIFY(text_of(r.find<QLabel>("droMarks_X")).contains("○"));
    QVERIFY(text_of(r.find<QLabel>("droMarks_X")).contains("+L"));
    QCOMPARE(text_of(r.find<QLabel>("homedLabel")), QString("NOT HOMED"));
    // Actual position: unknown until the feedback is valid.
    QTest::mouseClick(r.find<QPushButton>("droActual"), Qt::LeftButton);
    r.tick();
    QCOMPARE(text_of(r.find<QLabel>("droWork_X")), QString("unknown"));
  }
  void numbers_can_be_shown_with_a_comma() {
    MainWindow::Options opt;
    opt.number_comma = true;
    Rig r({}, kIni, opt);
    r.link->set_on();
    r.link->status.motion.position[0] = 101.25;
    r.tick();
    QCOMPARE(text_of(r.find<QLabel>("droMachine_X")), QString("101,250"));
  }
  void mode_strip_follows_the_controller() {
    Rig r;
    r.link->set_on(true, ipc::TaskMode::Mdi);
    r.tick();
    QVERIFY(r.find<QPushButton>("modeMdi")->isChecked());
    QVERIFY(!r.find<QPushButton>("modeManual")->isChecked());
    QTest::mouseClick(r.find<QPushButton>("modeAuto"), Qt::LeftButton);
    QCOMPARE(r.link->sent.size(), std::size_t(1));
    QCOMPARE(r.link->sent[0].type, CommandType::TaskSetMode);
    QCOMPARE(r.link->sent[0].i[0], 2);
    QVERIFY(!r.find<QPushButton>("modeAuto")->isChecked());  // until the controller says so
    r.link->status.task.mode = ipc::TaskMode::Auto;
    r.tick();
    QVERIFY(r.find<QPushButton>("modeAuto")->isChecked());
  }
  void estop_and_machine_buttons() {
    Rig r;
    r.tick();
    QTest::mouseClick(r.find<QPushButton>("estopButton"), Qt::LeftButton);
    QCOMPARE(r.link->sent.back().type, CommandType::TaskSetState);
    QCOMPARE(r.link->sent.back().i[0], 2);  // E-stop reset from E-stop
    QVERIFY(!r.find<QPushButton>("machineButton")->isEnabled());
    r.link->status.task.state = ipc::TaskState::EstopReset;
    r.tick();
    QTest::mouseClick(r.find<QPushButton>("machineButton"), Qt::LeftButton);
    QCOMPARE(r.link->sent.back().i[0], 4);
    r.link->set_on();
    r.tick();
    QTest::mouseClick(r.find<QPushButton>("estopButton"), Qt::LeftButton);
    QCOMPARE(r.link->sent.back().i[0], 1);
    QCOMPARE(r.link->estop_requests, 1);  // through the E-stop word first
  }
  // E-stop needs neither a command channel nor the task: the word is set
  // even when the command cannot be sent; a frozen status is shown as such.
  void estop_without_a_channel_and_a_stale_status_warning() {
    Rig r;
    r.link->set_on();
    r.tick();
    QVERIFY(!r.find<QLabel>("staleLabel")->isVisible());
    r.link->accept_sends = false;  // every channel taken
    QTest::mouseClick(r.find<QPushButton>("estopButton"), Qt::LeftButton);
    QCOMPARE(r.link->estop_requests, 1);
    r.w->activateWindow();
    QVERIFY(QTest::qWaitForWindowActive(r.w.get()));
    QTest::keyPress(r.w.get(), Qt::Key_F1);
    QCOMPARE(r.link->estop_requests, 2);
    r.link->live.task_stalled = true;
    r.link->live.status_age_ns = 2'300'000'000;
    r.tick();
    QVERIFY(r.find<QLabel>("staleLabel")->isVisible());
    QVERIFY(r.find<QLabel>("staleLabel")->text().contains("TASK STALLED 2.3 s"));
    QVERIFY(r.find<QLabel>("staleLabel")->text().contains("E-STOP still works"));
    r.link->live = {};
    r.tick();
    QVERIFY(!r.find<QLabel>("staleLabel")->isVisible());
  }
  void keyboard_jog_and_its_safety_rules() {
    Rig r;
    r.w->activateWindow();
    QVERIFY(QTest::qWaitForWindowActive(r.w.get()));
    r.link->set_on();
    r.tick();
    r.link->clear_sent();
    QTest::keyPress(r.w.get(), Qt::Key_Right);
    QCOMPARE(r.link->sent_of(CommandType::JogCont).size(), std::size_t(1));
    QCOMPARE(r.link->sent_of(CommandType::JogCont)[0].i[0], 0);
    QCOMPARE(r.link->sent_of(CommandType::JogCont)[0].d[0], 10.0);
    QTest::keyRelease(r.w.get(), Qt::Key_Right);
    QCOMPARE(r.link->sent_of(CommandType::JogStop).size(), std::size_t(1));
    // PageDown jogs Z down.
    QTest::keyPress(r.w.get(), Qt::Key_PageDown);
    QCOMPARE(r.link->sent_of(CommandType::JogCont).back().i[0], 2);
    QCOMPARE(r.link->sent_of(CommandType::JogCont).back().d[0], -10.0);
    // A mode change stops it.
    r.link->status.task.mode = ipc::TaskMode::Mdi;
    r.tick();
    QCOMPARE(r.link->sent_of(CommandType::JogStop).size(), std::size_t(2));
    QTest::keyRelease(r.w.get(), Qt::Key_PageDown);
    // With the MDI line focused the arrow keys edit text, never jog.
    r.link->status.task.mode = ipc::TaskMode::Manual;
    r.tick();
    r.w->tabs()->setCurrentIndex(1);
    auto* input = r.find<QLineEdit>("mdiInput");
    input->setFocus();
    QTRY_VERIFY(input->hasFocus());
    input->setText("G0 X1");
    const std::size_t jogs = r.link->sent_of(CommandType::JogCont).size();
    QTest::keyPress(input, Qt::Key_Left);
    QTest::keyRelease(input, Qt::Key_Left);
    QCOMPARE(r.link->sent_of(CommandType::JogCont).size(), jogs);
    QCOMPARE(input->cursorPosition(), 4);
    QVERIFY(!r.w->jog().keyboard_enabled());
  }
  void jog_buttons_and_increments() {
    Rig r;
    r.link->set_on();
    r.tick();
    r.link->clear_sent();
    auto* plus_y = r.find<QPushButton>("jogPlus_Y");
    QTest::mousePress(plus_y, Qt::LeftButton);
    QCOMPARE(r.link->sent.back().type, CommandType::JogCont);
    QCOMPARE(r.link->sent.back().i[0], 1);
    QTest::mouseRelease(plus_y, Qt::LeftButton);
    QCOMPARE(r.link->sent.back().type, CommandType::JogStop);
    QTest::mouseClick(r.find<QPushButton>("increment_2"), Qt::LeftButton);  // 0.1 mm
    QTest::mousePress(r.find<QPushButton>("jogMinus_X"), Qt::LeftButton);
    QCOMPARE(r.link->sent.back().type, CommandType::JogIncr);
    QCOMPARE(r.link->sent.back().d[1], -0.1);
    QTest::mouseRelease(r.find<QPushButton>("jogMinus_X"), Qt::LeftButton);
    // Not homed: the joint is jogged.
    r.link->status.joints[0].homed = false;
    r.tick();
    QTest::mousePress(r.find<QPushButton>("jogPlus_X"), Qt::LeftButton);
    QCOMPARE(r.link->sent.back().i[1], 1);
    QTest::mouseRelease(r.find<QPushButton>("jogPlus_X"), Qt::LeftButton);
    // The speed slider sets the jog velocity (units/min on the screen).
    r.find<QSlider>("jogSpeed")->setValue(1800);
    QCOMPARE(r.w->jog().linear_velocity(), 30.0);
    QCOMPARE(r.find<QSlider>("jogSpeed")->maximum(), 3000);  // MAX_LINEAR_VELOCITY 50/s
  }
  void mdi_history_keeps_only_executed_lines() {
    Rig r;
    r.link->set_on();
    r.tick();
    r.w->tabs()->setCurrentIndex(1);
    auto* input = r.find<QLineEdit>("mdiInput");
    input->setText("G0 X10 Y5");
    QTest::keyClick(input, Qt::Key_Return);
    QCOMPARE(r.link->sent.back().type, CommandType::TaskSetMode);  // MANUAL -> MDI first
    QCOMPARE(r.link->sent.back().i[0], 3);
    r.tick();
    QCOMPARE(r.link->sent.back().type, CommandType::TaskPlanExecute);
    QCOMPARE(std::string(r.link->sent.back().text.view()), std::string("G0 X10 Y5"));
    QCOMPARE(r.link->sent.back().i[0], -1);
    r.tick();
    const std::string file = r.dir.path().toStdString() + "/mdi_history.txt";
    QCOMPARE(read_file(file), std::string("G0 X10 Y5\n"));
    QCOMPARE(r.find<QListWidget>("mdiHistory")->count(), 1);
    // A rejected line is not kept.
    r.link->status.task.mode = ipc::TaskMode::Mdi;
    r.link->answers[CommandType::TaskPlanExecute] = {ipc::CommandState::Rejected, "line 1: G1 without F"};
    r.tick();
    input->setText("G1 X1");
    QTest::keyClick(input, Qt::Key_Return);
    r.tick(2);
    QCOMPARE(read_file(file), std::string("G0 X10 Y5\n"));
    bool logged = false;
    for (const auto& e : r.w->alarms().log()) logged = logged || e.text.find("G1 without F") != std::string::npos;
    QVERIFY(logged);
    // Again the first line (another spelling): still one entry.
    r.link->answers.clear();
    input->setText("g0 x10 y5");
    QTest::keyClick(input, Qt::Key_Return);
    r.tick(2);
    QCOMPARE(read_file(file), std::string("g0 x10 y5\n"));
  }
  void macro_buttons_run_the_mdi_command_list() {
    Rig r;
    r.link->set_on(true, ipc::TaskMode::Mdi);
    r.tick();
    auto* park = r.find<QPushButton>("macro_0");
    QCOMPARE(park->text(), QString("Park"));
    QCOMPARE(r.find<QPushButton>("macro_1")->text(), QString("Zero XY\nhere"));
    r.w->tabs()->setCurrentIndex(1);
    r.tick();
    QTest::mouseClick(r.find<QPushButton>("macro_1"), Qt::LeftButton);
    QCOMPARE(r.link->sent.back().type, CommandType::TaskPlanExecute);
    QCOMPARE(r.link->sent.back().i[0], 1);
  }
  void overrides_stay_within_the_ini_limits() {
    Rig r;
    r.link->set_on();
    r.tick();
    auto* feed = r.find<QSlider>("feedOverride");
    QCOMPARE(feed->maximum(), 150);
    QCOMPARE(r.find<QSlider>("spindleOverride")->minimum(), 50);
    QCOMPARE(r.find<QSlider>("spindleOverride")->maximum(), 120);
    QCOMPARE(r.find<QSlider>("rapidOverride")->maximum(), 100);
    QCOMPARE(r.find<QSlider>("maxVelocity")->maximum(), 6000);
    r.link->clear_sent();
    feed->setValue(120);
    QCOMPARE(r.link->sent.back().type, CommandType::TrajSetScale);
    QCOMPARE(r.link->sent.back().d[0], 1.2);
    QTest::mouseClick(r.find<QPushButton>("feedOverrideReset"), Qt::LeftButton);
    QCOMPARE(r.link->sent.back().d[0], 1.0);
    // The slider follows the controller (another client changed it).
    r.link->status.motion.feed_scale = 0.5;
    r.link->clear_sent();
    r.tick();
    QCOMPARE(feed->value(), 50);
    QVERIFY(r.link->sent.empty());
  }
  void alarms_stay_until_acknowledged() {
    Rig r;
    r.link->set_on();
    r.link->post(MessageKind::Error, "joint 1 following error", "motion");
    r.link->post(MessageKind::Error, "joint 1 following error", "motion");
    r.link->post(MessageKind::Text, "homing finished", "motion");
    r.tick();
    QCOMPARE(r.find<QPushButton>("alarmBadge")->text(), QString("ALARMS: 2"));
    QCOMPARE(r.find<QListWidget>("alarmList")->count(), 2);
    QTest::mouseClick(r.find<QPushButton>("alarmBadge"), Qt::LeftButton);
    QCOMPARE(r.w->tabs()->currentWidget()->objectName(), QString("alarmsPage"));
    QTest::mouseClick(r.find<QPushButton>("ackButton"), Qt::LeftButton);
    QCOMPARE(r.find<QListWidget>("alarmList")->count(), 1);
    QTest::mouseClick(r.find<QPushButton>("ackAllButton"), Qt::LeftButton);
    r.tick();
    QCOMPARE(r.find<QListWidget>("alarmList")->count(), 0);
    QCOMPARE(r.find<QPushButton>("alarmBadge")->text(), QString("No alarms"));
    QVERIFY(r.find<QPlainTextEdit>("logView")->toPlainText().contains("homing finished"));
  }
  void program_text_preview_and_executing_line() {
    Rig r;
    const std::string prog = r.write("part.ngc", "G21 G90\nG0 X10 Y10 Z5\nG1 Z-1 F100\nG1 X40\nG2 X40 Y30 I0 J10\nM2\n");
    r.link->set_on();
    r.tick();
    r.w->open_program(QString::fromStdString(prog));
    QCOMPARE(r.link->sent.back().type, CommandType::TaskPlanOpen);
    QCOMPARE(std::string(r.link->sent.back().text.view()), prog);
    r.link->status.task.file.assign(prog);
    r.link->status.task.total_lines = 6;
    r.tick();
    QCOMPARE(r.w->program_text()->blockCount(), 6);
    QTRY_VERIFY_WITH_TIMEOUT(!r.w->preview_busy(), 10000);
    QVERIFY(r.w->preview()->path());
    QVERIFY(r.w->preview()->path()->points.size() > 6);
    QVERIFY(r.w->preview()->limit_warning().isEmpty());
    r.link->status.task.interp_state = ipc::InterpState::Reading;
    r.link->status.task.current_line = 4;
    r.link->status.task.read_line = 5;
    r.tick();
    QCOMPARE(r.w->program_text()->executing_line(), 4);
    r.w->grab().save(screenshot_dir() + "/widget-program.png");
  }
  void preview_warns_about_soft_limits() {
    Rig r;
    const std::string prog = r.write("far.ngc", "G0 X0 Y0\nG1 X250 F500\nM2\n");  // G54 X100: machine X350
    r.link->set_on();
    r.link->status.task.file.assign(prog);
    r.tick();
    QTRY_VERIFY_WITH_TIMEOUT(!r.w->preview_busy(), 10000);
    QVERIFY(r.w->preview()->limit_warning().contains("X above"));
    QVERIFY(r.w->preview()->limit_warning().contains("line 2"));
    bool logged = false;
    for (const auto& e : r.w->alarms().log()) logged = logged || e.text.find("soft limits") != std::string::npos;
    QVERIFY(logged);
  }
  void run_from_line_previews_then_asks() {
    Rig r;
    const std::string prog = r.write("part.ngc", "G0 X1\nG0 X2\nG0 X3\nG0 X4\nM2\n");
    r.link->set_on(true, ipc::TaskMode::Auto);
    r.link->status.task.file.assign(prog);
    r.tick();
    r.link->clear_sent();
    r.w->request_run_from_line(3);
    QCOMPARE(r.link->sent.back().type, CommandType::TaskPlanRunPreview);
    QCOMPARE(r.link->sent.back().i[0], 3);
    r.tick();  // answer Done; the status does not show it yet
    QVERIFY(!r.w->findChild<QMessageBox*>("runFromLineDialog"));
    r.link->status.task.run_from_line_pending = 3;
    r.link->status.task.run_from_line_start[0] = 103;
    r.tick();
    auto* box = r.w->findChild<QMessageBox*>("runFromLineDialog");
    QVERIFY(box);
    QVERIFY(box->text().contains("103.000"));
    QVERIFY(r.link->sent_of(CommandType::TaskPlanRun).empty());  // nothing moves before the operator confirms
    QTest::mouseClick(box->findChild<QPushButton*>("runFromLineConfirm"), Qt::LeftButton);
    QCOMPARE(r.link->sent.back().type, CommandType::TaskPlanRun);
    QCOMPARE(r.link->sent.back().i[0], 3);
  }
  void tool_table_edits_go_to_the_controller() {
    Rig r;
    r.link->set_on();
    r.link->status.io.tool_in_spindle = 2;
    r.tick();
    r.w->tabs()->setCurrentIndex(2);
    r.tick();
    auto* table = r.find<QTableWidget>("toolTable");
    QCOMPARE(table->rowCount(), 2);
    QCOMPARE(table->item(1, 0)->text(), QString("2"));
    QCOMPARE(table->item(1, 2)->text(), QString("42.500"));
    table->item(1, 2)->setText("40,25");  // comma accepted
    QCOMPARE(r.link->sent.back().type, CommandType::ToolSetOffset);
    QCOMPARE(r.link->sent.back().i[0], 2);
    QCOMPARE(r.link->sent.back().i[1], -1);
    QCOMPARE(r.link->sent.back().d[2], 40.25);
    QCOMPARE(r.link->sent.back().d[9], 10.0);  // the rest of the tool unchanged
    QCOMPARE(std::string(r.link->sent.back().text.view()), std::string("10 mm end mill"));
    r.tick();
    // The screen never writes the file.
    QCOMPARE(read_file(r.dir.path().toStdString() + "/tool.tbl"),
             std::string("T1 P1 D6 Z+35 ;6 mm end mill\nT2 P2 D10 Z+42.5 ;10 mm end mill\n"));
    bool warned = false;
    for (const auto& e : r.w->alarms().log()) warned = warned || e.text.find("G43") != std::string::npos;
    QVERIFY(warned);  // the tool in the spindle was changed
    const std::size_t n = r.link->sent.size();
    table->item(0, 2)->setText("1.2.3");
    QCOMPARE(r.link->sent.size(), n);  // refused on the screen
    QTest::mouseClick(r.find<QPushButton>("toolReload"), Qt::LeftButton);
    QCOMPARE(r.link->sent.back().type, CommandType::ToolLoadTable);
  }
  void work_offsets_edit_through_the_controller() {
    Rig r;
    r.link->set_on();
    r.link->status.task.g5x_index = 1;
    r.link->status.task.g5x_offset[0] = 100;
    r.tick();
    r.w->tabs()->setCurrentIndex(3);
    r.tick();
    auto* table = r.find<QTableWidget>("offsetTable");
    QCOMPARE(table->item(0, 0)->text(), QString("100.000"));
    table->item(1, 0)->setText("12,5");  // G55 X
    QCOMPARE(r.link->sent.back().type, CommandType::SetWorkOffset);
    QCOMPARE(r.link->sent.back().i[0], 2);
    QCOMPARE(r.link->sent.back().d[0], 12.5);
    table->item(0, 3)->setText("30");  // G54 rotation
    QCOMPARE(r.link->sent.back().i[0], 1);
    QCOMPARE(r.link->sent.back().d[9], 30.0);
    QCOMPARE(r.link->sent.back().d[0], 100.0);
  }
  void touch_off_accepts_a_comma() {
    Rig r;
    r.link->set_on();
    r.link->status.motion.position[0] = 110;
    r.tick();
    QTest::mouseClick(r.find<QPushButton>("droSet_X"), Qt::LeftButton);
    auto* dialog = r.w->findChild<QInputDialog*>("touchOffDialog");
    QVERIFY(dialog);
    dialog->setTextValue("2,5");
    dialog->accept();
    QCOMPARE(r.link->sent.back().type, CommandType::SetWorkOffset);
    QCOMPARE(r.link->sent.back().i[0], 1);
    QCOMPARE(r.link->sent.back().d[0], 107.5);  // 110 - 2.5
    QTest::mouseClick(r.find<QPushButton>("droZero_X"), Qt::LeftButton);
    QCOMPARE(r.link->sent.back().d[0], 110.0);
  }
  void hal_pins_dialogs_and_postgui_in_order() {
    Rig r("[DISPLAY]\nMESSAGE_TEXT = Check the lube\nMESSAGE_TYPE = okdialog status\nMESSAGE_PINNAME = lube\n");
    r.link->set_on();
    r.tick();
    QTRY_VERIFY(!r.w->hal_setup_pending());
    const auto lines = r.hal();
    const auto pos = [&](const std::string& l) { return std::find(lines.begin(), lines.end(), l) - lines.begin(); };
    QCOMPARE(pos("newcomp hmi"), 0L);
    // The screen reads the POSTGUI file itself and sends its lines (the
    // controller never reads a file for a client).
    QVERIFY(pos("newpin hmi hmi.lube bit io") < pos("echo postgui file"));
    QVERIFY(pos("echo postgui file") < pos("echo after the postgui file"));
    QVERIFY(!contains(lines, "source " + r.dir.path().toStdString() + "/post.hal"));
    QVERIFY(pos("echo after the postgui file") < static_cast<long>(lines.size()));
    r.set_show_pin("hmi bit I/O TRUE hmi.lube\nhmi bit OUT FALSE hmi.lube-waiting\n");
    QTRY_VERIFY_WITH_TIMEOUT(r.w->findChild<QMessageBox*>("userDialog_lube"), 5000);
    auto* box = r.w->findChild<QMessageBox*>("userDialog_lube");
    QVERIFY(box->text().contains("Check the lube"));
    QTRY_VERIFY(contains(r.hal(), "setr hmi.lube-waiting TRUE"));
    box->button(QMessageBox::Ok)->click();
    QTRY_VERIFY(contains(r.hal(), "setr hmi.lube FALSE"));
    QCOMPARE(r.w->shown_user_dialogs(), 0);
  }
  void filter_programs_make_the_g_code() {
    Rig r;
    r.link->set_on();
    r.tick();
    const std::string src = r.write("drawing.txt", "anything\n");
    r.w->open_program(QString::fromStdString(src));
    QTRY_VERIFY_WITH_TIMEOUT(!r.link->sent_of(CommandType::TaskPlanOpen).empty(), 10000);
    const std::string out(r.link->sent_of(CommandType::TaskPlanOpen).back().text.view());
    QVERIFY(out.size() > 4 && out.substr(out.size() - 4) == ".ngc");
    QCOMPARE(read_file(out), std::string("G0 X1 Y2\nM2\n"));
  }
  void drives_page_decodes_faults() {
    Rig r;
    r.link->set_on();
    auto& d = r.link->status.drives[0];
    d.present = true;
    d.joint = 0;
    d.name.assign("x-drive");
    d.state = 7;
    d.statusword = 0x0218;
    d.error_code = 0x8611;
    d.torque_percent = 12.5;
    r.w->tabs()->setCurrentIndex(5);
    r.tick();
    auto* table = r.find<QTableWidget>("driveTable");
    QVERIFY(table->item(0, 1)->text().startsWith("x-drive: fault"));
    QVERIFY(table->item(0, 3)->text().contains("following error"));
    QCOMPARE(table->item(0, 2)->text(), QString("0x0218 F VE RM"));
    QVERIFY(r.find<QLabel>("driveStatuswordDetail")->text().contains("0x0218: fault, voltage enabled, remote"));
    QCOMPARE(table->item(0, 5)->text(), QString("12.5 %"));
    QVERIFY(table->item(0, 6)->text().endsWith(" mm/s"));
    // The fake controller keeps no alarm table: the screen raises the drive's.
    QCOMPARE(r.w->alarms().active_count(), std::size_t(1));
    r.w->grab().save(screenshot_dir() + "/widget-drives.png");
  }
  // The Probe page runs a bore routine stage by stage: each stage's MDI
  // lines, the probe result read from the status after the stage, the
  // centre and diameters shown, G55's origin set.
  void probe_page_runs_a_bore_with_the_probe_results_from_the_status() {
    Rig r("[PROBE]\nTIP_DIAMETER = 2\nSEARCH_DISTANCE = 10\nLATCH_DISTANCE = 1\nSEARCH_FEED = 300\nLATCH_FEED = 25\n");
    r.link->set_on();
    r.link->status.motion.position[0] = 100;
    r.link->status.motion.position[1] = 50;
    r.link->status.motion.position[2] = -10;
    r.show("probePage");
    r.tick();
    r.find<QComboBox>("probeRoutine")->setCurrentIndex(7);  // bore
    r.find<QComboBox>("probeSystem")->setCurrentIndex(2);   // G55
    QVERIFY(r.find<QPushButton>("probeStart")->isEnabled());
    r.find<QPushButton>("probeStart")->click();
    auto* result = r.find<QLabel>("probeResult");
    const std::vector<double> hits = {108, 94, 57, 45, 108, 94};
    const int axes[] = {0, 0, 1, 1, 0, 0};
    std::size_t k = 0, probes_seen = 0;
    for (int i = 0; i < 500 && text_of(result) == QString("Probing…"); ++i) {
      r.tick();
      const auto lines = r.mdi_lines();
      const auto probes = static_cast<std::size_t>(std::count(lines.begin(), lines.end(), std::string("G90")));
      if (probes > probes_seen && k < hits.size()) {  // a probe stage was sent: its result comes in the status
        probes_seen = probes;
        r.link->status.motion.probe_tripped = true;
        r.link->status.motion.probed_position[axes[k]] = hits[k];
        ++k;
      }
    }
    QVERIFY2(text_of(result).startsWith("centre at machine X 101.0000 Y 51.0000, diameter X 16.0000 Y 14.0000; G55 set"),
             qPrintable(text_of(result)));
    const auto lines = r.mdi_lines();
    QCOMPARE(lines.front(), std::string("M70"));  // the modal state saved first ...
    QCOMPARE(lines.at(2), std::string("G91 G38.2 X10.0000 F300.0000"));
    QVERIFY(contains(lines, "G53 G0 X101.0000"));
    QVERIFY(contains(lines, "G10 L2 P2 X101.0000 Y51.0000"));
    QCOMPARE(lines.at(lines.size() - 2), std::string("M72"));  // ... and restored at the end
    QCOMPARE(lines.back(), std::string("M71"));
    r.w->grab().save(screenshot_dir() + "/widget-probe.png");
  }

  void probe_page_stops_when_the_probe_finds_nothing_and_restores_the_modal_state() {
    Rig r;
    r.link->set_on();
    // The operator's modal state: inch, incremental, F12.
    const int gcodes[] = {10, 170, 910, 911, 940, 200};
    std::fill(std::begin(r.link->status.task.active_gcodes), std::end(r.link->status.task.active_gcodes), -1);
    std::copy(std::begin(gcodes), std::end(gcodes), r.link->status.task.active_gcodes);
    r.link->status.task.active_settings[1] = 12;
    r.show("probePage");
    r.tick();
    r.find<QComboBox>("probeRoutine")->setCurrentIndex(1);  // edge X+
    r.find<QPushButton>("probeStart")->click();
    auto* result = r.find<QLabel>("probeResult");
    for (int i = 0; i < 100 && text_of(result) == QString("Probing…"); ++i) r.tick();  // probe_tripped stays FALSE
    QCOMPARE(text_of(result), QString("Failed: edge: probe X+: no contact within the search distance"));
    r.tick(5);
    // The abort reset the interpreter (and the M70 context): the start's
    // modal state is sent back explicitly.
    QCOMPARE(r.mdi_lines().at(r.mdi_lines().size() - 2), std::string("G20 G91 G94 G17"));
    QCOMPARE(r.mdi_lines().back(), std::string("F12.0000"));
    // Touch-off into a coordinate system that is not the active one.
    r.find<QComboBox>("touchAxis")->setCurrentIndex(2);    // Z
    r.find<QComboBox>("touchSystem")->setCurrentIndex(8);  // G59.3
    r.find<QLineEdit>("touchValue")->setText("-1,5");
    r.tick();
    r.find<QPushButton>("touchOffButton")->click();
    r.tick(3);  // MDI mode first
    QCOMPARE(r.mdi_lines().back(), std::string("G10 L20 P9 Z-1.5000"));
  }

  // The Scope page drives the controller's scope with halcmd lines: stop,
  // setup, arm, state until done, csv; the capture is plotted and exported.
  void scope_page_sets_up_arms_polls_plots_and_exports() {
    Rig r;
    const std::string csv = "time_s,a.b,c.d\n-0.001000,1,2\n0.000000,2,3\n0.001000,3,1\n";
    r.set_reply("scope state", "done samples=3 pre=1 channels=2\n");
    r.set_reply("scope csv", csv);
    r.link->set_on();
    r.show("scopePage");
    r.tick();
    r.find<QLineEdit>("scopePins")->setText("a.b c.d");
    r.find<QLineEdit>("scopeTrigger")->setText("c.d");
    r.find<QLineEdit>("scopeLevel")->setText("2,5");
    r.find<QPushButton>("scopeRun")->click();
    auto* state = r.find<QLabel>("scopeState");
    QTRY_VERIFY_WITH_TIMEOUT((r.tick(), text_of(state).startsWith("Capture 1: 3 samples")), 5000);
    const auto hal = r.hal();
    std::vector<std::string> scope_lines;
    for (const auto& l : hal) {
      if (l.rfind("scope", 0) == 0) scope_lines.push_back(l);
    }
    QVERIFY(scope_lines.size() >= 5);
    QCOMPARE(scope_lines[0], std::string("scope stop"));
    QCOMPARE(scope_lines[1], std::string("scope setup a.b,c.d trigger=c.d edge=rising level=2.5 pre=10 mode=single"));
    QCOMPARE(scope_lines[2], std::string("scope arm"));
    QCOMPARE(scope_lines[3], std::string("scope state"));
    QCOMPARE(scope_lines.back(), std::string("scope csv"));
    auto* view = r.find<QChartView>("scopeChart");
    QCOMPARE(view->chart()->series().size(), 2);
    // Each pin on its own scale by default, its range in the legend.
    QCOMPARE(view->chart()->series()[0]->name(), QString("a.b (1 … 3)"));
    r.find<QCheckBox>("scopeNormalise")->setChecked(false);
    QCOMPARE(view->chart()->series()[0]->name(), QString("a.b"));
    QVERIFY(r.find<QPushButton>("scopeRun")->isEnabled());  // single: done
    const QString out = r.dir.path() + "/capture.csv";
    QVERIFY(r.w->findChild<ScopePage*>("scopePage")->export_csv(out));
    QCOMPARE(read_file(out.toStdString()), csv);
    r.w->grab().save(screenshot_dir() + "/widget-scope.png");
  }

  void scope_page_shows_the_controllers_refusal() {
    Rig r;
    r.set_reply("scope setup", "ERROR scope: no scope loaded (loadrt scope [samples=N], addf scope.sample servo-thread)");
    r.show("scopePage");
    r.tick();
    r.find<QPushButton>("scopeRun")->click();
    auto* state = r.find<QLabel>("scopeState");
    QTRY_VERIFY_WITH_TIMEOUT((r.tick(), text_of(state).startsWith("Scope: scope: no scope loaded")), 5000);
    QVERIFY(r.find<QPushButton>("scopeRun")->isEnabled());
    QVERIFY(!r.w->findChild<ScopePage*>("scopePage")->capturing());
  }

  void lathe_layout() {
    std::string ini = kIni;
    ini.replace(ini.find("COORDINATES = X Y Z"), 19, "COORDINATES = X Z");
    ini.replace(ini.find("coordinates=XYZ\nJOINTS = 3"), 26, "coordinates=XZ\nJOINTS = 2");
    Rig r("[DISPLAY]\nMACHINE_TYPE_HINT = LATHE\n", ini);
    QVERIFY(r.w->config().lathe);
    QVERIFY(r.w->findChild<QLabel*>("droWork_X"));
    QVERIFY(r.w->findChild<QLabel*>("droWork_Z"));
    QVERIFY(!r.w->findChild<QLabel*>("droWork_Y"));
    QCOMPARE(r.w->preview()->view(), PreviewWidget::View::Lathe);
    r.link->set_on();
    r.link->status.motion.joints = 2;
    r.link->status.joints[1].axis = 2;
    r.link->status.task.g5x_offset = Pose{};
    r.link->status.motion.position[0] = 12.5;  // radius
    r.link->status.task.active_gcodes[2] = 70;  // G7: diameter
    r.tick();
    QCOMPARE(text_of(r.find<QLabel>("droWork_X")), QString("25.000"));
    QVERIFY(r.find<QTableWidget>("toolTable")->columnCount() > 5);  // X, Z, angles, orientation
    r.w->grab().save(screenshot_dir() + "/widget-lathe.png");
  }
  void fits_a_1024_by_768_screen() {
    Rig r;
    r.link->set_on();
    r.tick();
    QString widths;
    for (int i = 0; i < r.w->tabs()->count(); ++i) {
      widths += QString(" %1=%2x%3").arg(r.w->tabs()->widget(i)->objectName()).arg(r.w->tabs()->widget(i)->minimumSizeHint().width()).arg(r.w->tabs()->widget(i)->minimumSizeHint().height());
    }
    QVERIFY2(r.w->minimumSizeHint().width() <= 1024, qPrintable(QString("%1 px; pages:%2").arg(r.w->minimumSizeHint().width()).arg(widths)));
    QVERIFY2(r.w->minimumSizeHint().height() <= 768, qPrintable(QString("%1 px; pages:%2").arg(r.w->minimumSizeHint().height()).arg(widths)));
    r.w->resize(1024, 768);
    QCoreApplication::processEvents();
    for (const char* name : {"estopButton", "machineButton", "modeAuto", "alarmBadge", "runButton", "abortButton",
                             "blockDelete", "homeAllButton", "jogPlus_Z", "droWork_X"}) {
      auto* wdg = r.w->findChild<QWidget*>(name);
      QVERIFY2(wdg, name);
      const QRect rect(wdg->mapTo(r.w.get(), QPoint(0, 0)), wdg->size());
      QVERIFY2(r.w->rect().contains(rect), name);
      QVERIFY2(wdg->height() >= 24, name);
    }
    r.w->grab().save(screenshot_dir() + "/widget-1024x768.png");
  }
  void embedded_tabs_get_a_window_to_embed_into() {
    MainWindow::Options opt;
    Rig r("[DISPLAY]\nEMBED_TAB_NAME = Probe panel\nEMBED_TAB_COMMAND = echo {XID} > xid.txt\n", kIni, opt, true);
    const int last = r.w->tabs()->count() - 1;
    QCOMPARE(r.w->tabs()->tabText(last), QString("Probe panel"));
    r.w->tabs()->setCurrentIndex(last);  // started when first shown
    const QString file = r.dir.path() + "/xid.txt";
    QTRY_VERIFY_WITH_TIMEOUT(QFileInfo(file).size() > 0, 5000);
    QFile f(file);
    QVERIFY(f.open(QIODevice::ReadOnly));
    const QWidget* container = r.w->tabs()->widget(last)->findChild<QWidget*>("embedContainer");
    QVERIFY(container);
    QCOMPARE(f.readAll().trimmed().toULongLong(), static_cast<qulonglong>(container->winId()));
  }
  void joints_home_one_by_one_from_the_drives_page() {
    Rig r;
    r.link->set_on(false);
    r.w->tabs()->setCurrentIndex(5);
    r.tick();
    QTest::mouseClick(r.find<QPushButton>("homeJoint_2"), Qt::LeftButton);
    QCOMPARE(r.link->sent.back().type, CommandType::JointHome);
    QCOMPARE(r.link->sent.back().i[0], 2);
  }
  void without_a_controller_everything_waits() {
    Rig r;
    r.link->connected = false;
    r.tick();
    QCOMPARE(text_of(r.find<QLabel>("stateLabel")), QString("NO CONTROLLER"));
    QVERIFY(!r.find<QPushButton>("runButton")->isEnabled());
    QVERIFY(!r.find<QPushButton>("estopButton")->isEnabled());
    QTest::mousePress(r.find<QPushButton>("jogPlus_X"), Qt::LeftButton);
    QVERIFY(r.link->sent.empty());
    r.link->connected = true;
    r.tick();
    QVERIFY(r.find<QPushButton>("estopButton")->isEnabled());
  }
};

int main(int argc, char** argv) {
  if (!qEnvironmentVariableIsSet("QT_QPA_PLATFORM")) qputenv("QT_QPA_PLATFORM", "offscreen");
  QApplication app(argc, argv);
  QApplication::setStyle("Fusion");
  WidgetTests t;
  return QTest::qExec(&t, argc, argv);
}
#include "widget_tests.moc"
