// End to end: the controller daemon (cncd) on a copy of the simulated mill
// (configs/sim) and the operator screen in this process, under Xvfb. The
// test drives the screen like an operator (clicks and key presses on its
// widgets), checks the controller's state after each action through its
// own ipc::Client, and saves a screenshot of every step to
// <build>/hmi-screenshots/e2e-*.png for review and as CI artifacts.
#include <unistd.h>

#include <QApplication>
#include <QDir>
#include <QHeaderView>
#include <QScrollBar>
#include <QtCharts/QChartView>
#include <QLabel>
#include <QLineEdit>
#include <QComboBox>
#include <QSpinBox>
#include <QMessageBox>
#include <QProcess>
#include <QScreen>
#include <QPushButton>
#include <QTabWidget>
#include <QTableWidget>
#include <QTemporaryDir>
#include <QtTest>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "core/ini/ini_file.hpp"
#include "core/ipc/admin.hpp"
#include "core/ipc/client.hpp"
#include "core/tooltable/tool_table.hpp"
#include "core/util/atomic_file.hpp"
#include "hmi/main_window.hpp"
#include "hmi/positions.hpp"
#include "hmi/preview_widget.hpp"
#include "hmi/panels.hpp"
#include "hmi/probing.hpp"

using namespace cnc;
using namespace cnc::hmi;

namespace {

// Lines are numbered for the run-from-line step.
const char* kProgram =
    "G21 G90 G17 G94\n"           // 1
    "G10 L2 P1 X100 Y50 Z-80\n"   // 2
    "G54\n"                       // 3
    "G0 X10 Y10 Z5\n"             // 4
    "G1 Z-1 F600\n"               // 5
    "G1 X40 F1500\n"              // 6
    "G2 X40 Y30 I0 J10\n"         // 7
    "G1 X10\n"                    // 8
    "G1 Y10\n"                    // 9
    "G0 Z5\n"                     // 10
    "G0 X20 Y20\n"                // 11
    "M2\n";                       // 12

// Extra INI keys for the test: history file, a HAL-driven dialog and a
// POSTGUI command that needs the screen's pin to exist.
const char* kExtraIni =
    "\n[DISPLAY]\n"
    "MDI_HISTORY_FILE = mdi_history.txt\n"
    "MESSAGE_BOLDTEXT = Lubrication\nMESSAGE_TEXT = Check the way oil level\n"
    "MESSAGE_TYPE = okdialog status\nMESSAGE_PINNAME = e2e-note\n"
    "\n[HAL]\nPOSTGUI_HALCMD = net e2e-note-signal hmi.e2e-note\n"
    // The tool setter of configs/sim trips at table Z -100 (machine Z near
    // -100); a tool of length 0 would touch it at Z -118.
    "\n[PROBE]\nTIP_DIAMETER = 2\nSEARCH_DISTANCE = 10\nLATCH_DISTANCE = 1\nSEARCH_FEED = 300\nLATCH_FEED = 30\n"
    "SETTER_X = 250\nSETTER_Y = 150\nSETTER_Z = -85\nSETTER_SAFE_Z = 0\nSETTER_REFERENCE_Z = -118\n"
    "SETTER_SEARCH_DISTANCE = 32\n";

}  // namespace

class E2eTests : public QObject {
  Q_OBJECT

  QTemporaryDir dir_{QDir::tempPath() + "/cnc-hmi-e2e-XXXXXX"};
  std::string instance_ = "hmi-e2e-" + std::to_string(::getpid());
  std::filesystem::path run_;
  QProcess cncd_;
  std::unique_ptr<ipc::Client> client_;
  std::unique_ptr<MainWindow> w_;
  QString shots_;
  int shot_ = 0;

  ipc::Status st() { return client_->status(); }

  bool wait_for(const std::function<bool(const ipc::Status&)>& pred, int ms) {
    return QTest::qWaitFor([&]() { return pred(st()); }, ms);
  }

  void shot(const QString& name) {
    for (int i = 0; i < 3; ++i) QTest::qWait(60);  // a few screen cycles
    const QString file = QString("%1/e2e-%2-%3.png").arg(shots_).arg(++shot_, 2, 10, QChar('0')).arg(name);
    // The X screen under the window, so dialogs on top of it are in the picture.
    const QRect g = w_->frameGeometry();
    QPixmap pix = w_->QWidget::screen()->grabWindow(0, g.x(), g.y(), g.width(), g.height());
    if (pix.isNull()) pix = w_->grab();
    QVERIFY2(pix.save(file), qPrintable(file));
  }

  QPushButton* button(const char* name) {
    auto* b = w_->findChild<QPushButton*>(name);
    if (!b) qWarning("no button %s", name);
    return b;
  }
  void click(const char* name) {
    QPushButton* b = button(name);
    QVERIFY2(b, name);
    QTRY_VERIFY2_WITH_TIMEOUT(b->isEnabled(), name, 15000);  // generous: CI runs this beside the VM tests
    QTest::mouseClick(b, Qt::LeftButton);
  }
  void show_tab(const QString& object_name) {
    for (int i = 0; i < w_->tabs()->count(); ++i) {
      if (w_->tabs()->widget(i)->objectName() == object_name) w_->tabs()->setCurrentIndex(i);
    }
  }
  void mdi(const QString& line) {
    show_tab("mdiPage");
    auto* input = w_->findChild<QLineEdit*>("mdiInput");
    QVERIFY(input);
    input->setText(line);
    QTest::keyClick(input, Qt::Key_Return);
  }
  std::string hal(const std::string& line) {
    ipc::AdminClient admin(instance_);
    const auto r = admin.request(line);
    return r.ok ? std::string(trim(r.text)) : "ERROR: " + r.text;
  }
  static std::string trim(const std::string& s) {
    const auto a = s.find_first_not_of(" \n\t"), b = s.find_last_not_of(" \n\t");
    return a == std::string::npos ? std::string() : s.substr(a, b - a + 1);
  }
  static bool near(double a, double b) { return std::fabs(a - b) < 2e-3; }

 private slots:
  void initTestCase() {
    QVERIFY(dir_.isValid());
    shots_ = QString(CNC_BINARY_DIR) + "/hmi-screenshots";
    QDir().mkpath(shots_);
    for (const auto& old : QDir(shots_).entryList({"e2e-*.png"})) QFile::remove(shots_ + "/" + old);
    run_ = std::filesystem::path(dir_.path().toStdString()) / "sim";
    std::filesystem::copy(std::filesystem::path(CNC_SOURCE_DIR) / "configs/sim", run_, std::filesystem::copy_options::recursive);
    std::ofstream(run_ / "sim.ini", std::ios::app) << kExtraIni;
    std::ofstream(run_ / "nc_files/e2e.ngc") << kProgram;
    // The HAL scope for the Scope page (as tests/system/scope_capture.sh).
    std::ofstream(run_ / "sim.hal", std::ios::app) << "\nloadrt scope samples=2000\naddf scope.sample servo-thread\n";
    cncd_.setProgram(QString(CNC_BINARY_DIR) + "/bin/cncd");
    cncd_.setArguments({"--instance", QString::fromStdString(instance_), QString::fromStdString((run_ / "sim.ini").string())});
    cncd_.setStandardErrorFile(QString::fromStdString((run_ / "cncd.log").string()));
    auto env = QProcessEnvironment::systemEnvironment();
    env.insert("CNC_NO_REALTIME", "1");
    cncd_.setProcessEnvironment(env);
    cncd_.start();
    QVERIFY(cncd_.waitForStarted(5000));
    const bool ready = QTest::qWaitFor([&]() {
      try {
        if (!client_) client_ = std::make_unique<ipc::Client>(instance_);
        return client_->controller_ready();
      } catch (const std::exception&) {
        client_.reset();
        return cncd_.state() != QProcess::Running;
      }
    }, 30000);
    QVERIFY2(ready && client_, qPrintable("cncd did not come up; see " + QString::fromStdString((run_ / "cncd.log").string())));
    const ini::IniFile ini = ini::IniFile::load(run_ / "sim.ini");
    w_ = std::make_unique<MainWindow>(HmiConfig::from_ini(ini), UserDialogConfig::from_ini(ini),
                                      std::make_unique<ClientLink>(instance_), make_admin_executor(instance_),
                                      MainWindow::Options{});
    w_->resize(1280, 800);
    w_->show();
    QVERIFY(QTest::qWaitForWindowExposed(w_.get()));
    w_->activateWindow();
  }

  void cleanupTestCase() {
    w_.reset();
    if (client_) {
      try {
        client_->execute(ipc::make_command(ipc::CommandType::Shutdown), std::chrono::seconds(10));
      } catch (const std::exception&) {
      }
    }
    client_.reset();
    if (!cncd_.waitForFinished(10000)) cncd_.kill();
  }

  void t01_screen_connects_in_estop() {
    auto* state = w_->findChild<QLabel*>("stateLabel");
    QTRY_VERIFY_WITH_TIMEOUT(state->text().startsWith("ESTOP"), 5000);
    QCOMPARE(st().task.state, ipc::TaskState::Estop);
    QCOMPARE(button("estopButton")->text(), QString("E-STOP\nRESET"));
    shot("start-estop");
  }

  void t02_estop_reset_and_machine_on() {
    click("estopButton");
    QVERIFY(wait_for([](const ipc::Status& s) { return s.task.state == ipc::TaskState::EstopReset; }, 10000));
    click("machineButton");
    QVERIFY(wait_for([](const ipc::Status& s) { return s.task.state == ipc::TaskState::On && s.motion.enabled; }, 10000));
    QTRY_VERIFY(button("machineButton")->isChecked());
    shot("machine-on");
  }

  void t03_home_all() {
    click("homeAllButton");
    QVERIFY(wait_for([](const ipc::Status& s) {
      for (int j = 0; j < s.motion.joints; ++j) {
        if (!s.joints[j].homed) return false;
      }
      return s.motion.joints > 0;
    }, 120000));
    QTRY_COMPARE(w_->findChild<QLabel*>("homedLabel")->text(), QString("HOMED"));
    QVERIFY(w_->findChild<QLabel*>("droMarks_X")->text().contains("●"));
    shot("homed");
  }

  void t04_mdi_moves_and_is_remembered() {
    mdi("G53 G0 X100 Y50 Z-10");
    QVERIFY(wait_for([](const ipc::Status& s) {
      return s.task.interp_state == ipc::InterpState::Idle && near(s.motion.position[0], 100) &&
             near(s.motion.position[1], 50) && near(s.motion.position[2], -10);
    }, 30000));
    QCOMPARE(st().task.mode, ipc::TaskMode::Mdi);  // the screen switched the mode for MDI
    QTRY_VERIFY(QFile::exists(QString::fromStdString((run_ / "mdi_history.txt").string())));
    QTRY_COMPARE(QString::fromStdString(read_file(run_ / "mdi_history.txt")), QString("G53 G0 X100 Y50 Z-10\n"));
    QTRY_COMPARE(w_->findChild<QLabel*>("droMachine_X")->text(), QString("100.000"));
    shot("mdi");
  }

  void t05_incremental_jog() {
    click("modeManual");
    QVERIFY(wait_for([](const ipc::Status& s) { return s.task.mode == ipc::TaskMode::Manual; }, 10000));
    QTRY_VERIFY(button("modeManual")->isChecked());  // the screen has seen it too
    click("increment_1");  // 1 mm
    QTRY_VERIFY(button("jogPlus_X")->isEnabled());
    QTest::mousePress(button("jogPlus_X"), Qt::LeftButton);
    QTest::mouseRelease(button("jogPlus_X"), Qt::LeftButton);
    QVERIFY(wait_for([](const ipc::Status& s) { return near(s.motion.position[0], 101) && s.motion.inpos; }, 10000));
    click("increment_0");  // back to continuous
    shot("jogged");
  }

  void t06_open_program_and_preview() {
    const QString prog = QString::fromStdString((run_ / "nc_files/e2e.ngc").string());
    w_->open_program(prog);
    QVERIFY(wait_for([&](const ipc::Status& s) { return std::string(s.task.file.view()) == prog.toStdString(); }, 10000));
    QCOMPARE(st().task.total_lines, 12);
    QTRY_VERIFY_WITH_TIMEOUT(!w_->preview_busy() && w_->preview()->path(), 20000);
    QVERIFY(w_->preview()->path()->error.empty());
    QVERIFY(w_->preview()->path()->points.size() > 20);
    QVERIFY(w_->preview()->limit_warning().isEmpty());
    // The path is in machine coordinates with G54 X100 Y50 Z-80 from the program.
    QVERIFY(near(w_->preview()->path()->max[0], 140));
    QCOMPARE(w_->tabs()->currentWidget()->objectName(), QString("programPage"));  // opening shows the program
    // the planner's motion time (cnc-estimate run by the screen) beside the progress
    auto* progress = w_->findChild<QLabel*>("programProgress");
    QVERIFY(progress != nullptr);
    QTRY_VERIFY2_WITH_TIMEOUT(progress->text().contains("planned 0:0"), qPrintable(progress->text()), 20000);
    shot("program-loaded");
    w_->preview()->set_view(PreviewWidget::View::Z);
    shot("preview-top-view");
    w_->preview()->set_view(PreviewWidget::View::Perspective);
  }

  void t07_run_program() {
    click("runButton");
    QVERIFY(wait_for([](const ipc::Status& s) { return s.task.interp_state != ipc::InterpState::Idle; }, 10000));
    QCOMPARE(st().task.mode, ipc::TaskMode::Auto);
    QVERIFY(wait_for([](const ipc::Status& s) { return s.task.current_line >= 7; }, 60000));
    shot("running");
    QVERIFY(button("pauseButton")->isEnabled());
    QVERIFY(!button("runButton")->isEnabled());
    QVERIFY(wait_for([](const ipc::Status& s) { return s.task.interp_state == ipc::InterpState::Idle; }, 120000));
    const ipc::Status s = st();
    QCOMPARE(s.task.errors_since_start, 0);
    QVERIFY(near(s.motion.position[0], 120) && near(s.motion.position[1], 70) && near(s.motion.position[2], -75));
    QVERIFY(w_->preview()->backplot_size() > 10);
    shot("program-done");
  }

  void t08_alarm_is_acknowledged() {
    const std::size_t before = w_->alarms().active_count();
    mdi("G53 G1 X1000 F100");  // beyond the soft limit: the controller refuses
    QTRY_VERIFY_WITH_TIMEOUT(w_->alarms().active_count() > before, 10000);
    QTRY_VERIFY(button("alarmBadge")->text().startsWith("ALARMS"));
    const ipc::Status s = st();
    QCOMPARE(s.task.state, ipc::TaskState::On);
    QVERIFY(near(s.motion.position[0], 120));  // nothing moved
    click("alarmBadge");
    shot("alarm");
    // The controller keeps the alarms: one alarm for the refused line, and
    // acknowledging goes through it (the screen follows its status).
    QVERIFY(w_->alarms().controller_keeps_alarms());
    QVERIFY(st().alarms.active >= 1);
    click("ackAllButton");
    QTRY_COMPARE_WITH_TIMEOUT(w_->alarms().active_count(), std::size_t(0), 5000);
    QTRY_COMPARE(st().alarms.active, 0u);
    QTRY_COMPARE(button("alarmBadge")->text(), QString("No alarms"));
    shot("alarm-acknowledged");
  }

  void t09_run_from_line_with_approach() {
    show_tab("programPage");
    w_->request_run_from_line(8);
    QTRY_VERIFY_WITH_TIMEOUT(w_->findChild<QMessageBox*>("runFromLineDialog"), 10000);
    QCOMPARE(st().task.run_from_line_pending, 8);
    QCOMPARE(st().task.interp_state, ipc::InterpState::Idle);  // shown, not moved
    auto* box = w_->findChild<QMessageBox*>("runFromLineDialog");
    QVERIFY(box->text().contains("140.000"));  // the start of line 8: end of the arc, X40 in G54
    shot("run-from-line-approach");
    QTest::mouseClick(box->findChild<QPushButton*>("runFromLineConfirm"), Qt::LeftButton);
    QVERIFY(wait_for([](const ipc::Status& s) { return s.task.interp_state != ipc::InterpState::Idle; }, 10000));
    QVERIFY(wait_for([](const ipc::Status& s) { return s.task.interp_state == ipc::InterpState::Idle; }, 120000));
    const ipc::Status s = st();
    QCOMPARE(s.task.errors_since_start, 0);
    QVERIFY(near(s.motion.position[0], 120) && near(s.motion.position[1], 70));
    shot("run-from-line-done");
  }

  void t10_hal_dialog_and_postgui() {
    // POSTGUI_HALCMD ran after the screen made its pin: the signal exists.
    QTRY_VERIFY_WITH_TIMEOUT(hal("gets e2e-note-signal") == "FALSE", 10000);
    QCOMPARE(hal("sets e2e-note-signal TRUE"), std::string());
    QTRY_VERIFY_WITH_TIMEOUT(w_->findChild<QMessageBox*>("userDialog_e2e-note"), 5000);
    QTRY_COMPARE(hal("getp hmi.e2e-note-waiting"), std::string("TRUE"));
    shot("hal-dialog");
    w_->findChild<QMessageBox*>("userDialog_e2e-note")->button(QMessageBox::Ok)->click();
    QTRY_COMPARE_WITH_TIMEOUT(hal("getp hmi.e2e-note"), std::string("FALSE"), 5000);
    QTRY_COMPARE(hal("getp hmi.e2e-note-waiting"), std::string("FALSE"));
  }

  void t11_tool_table_edit_goes_through_the_controller() {
    show_tab("toolPage");
    auto* table = w_->findChild<QTableWidget*>("toolTable");
    QTRY_VERIFY(table->rowCount() >= 4);
    QCOMPARE(table->item(0, 0)->text(), QString("1"));
    table->item(0, 2)->setText("36,5");
    QTRY_VERIFY_WITH_TIMEOUT(
        [&]() {
          const auto t = tooltable::ToolTable::load(run_ / "tool.tbl", tooltable::ChangerKind::NonRandom);
          const auto idx = t.find_tool(1);
          return idx && near(t.at(*idx).offset[2], 36.5);
        }(),
        10000);
    QTRY_COMPARE(w_->findChild<QTableWidget*>("toolTable")->item(0, 2)->text(), QString("36.500"));
    shot("tools");
  }

  void t12_work_offset_edit_goes_through_the_controller() {
    show_tab("offsetsPage");
    auto* table = w_->findChild<QTableWidget*>("offsetTable");
    QTRY_COMPARE(table->item(0, 0)->text(), QString("100.000"));  // G54 from the program
    table->item(1, 0)->setText("5,5");                              // G55 X
    QTRY_VERIFY_WITH_TIMEOUT(read_work_offsets(run_ / "sim.var").g5x[1][0] == 5.5, 10000);
    shot("offsets");
  }

  void t13_other_pages() {
    show_tab("drivesPage");
    auto* drives = w_->findChild<QTableWidget*>("driveTable");
    QTRY_COMPARE(drives->rowCount() >= st().motion.joints, true);
    shot("drives");
    show_tab("alarmsPage");
    shot("log");
    show_tab("mdiPage");
    shot("mdi-page");
    show_tab("programPage");
    w_->resize(1024, 768);
    shot("1024x768");
    w_->resize(1280, 800);
  }

  // The drive page at both screen sizes: no horizontal scrolling, units in
  // the headers and cells, the statusword decoded, the trends drawn.
  void t13b_drives_page_fits_both_sizes_with_units_and_trends() {
    show_tab("drivesPage");
    auto* drives = w_->findChild<QTableWidget*>("driveTable");
    QVERIFY(drives);
    // The window (its widest page included) fits 1024 px.
    QString widths;
    for (int i = 0; i < w_->tabs()->count(); ++i) {
      widths += QString(" %1=%2").arg(w_->tabs()->widget(i)->objectName()).arg(w_->tabs()->widget(i)->minimumSizeHint().width());
    }
    for (const char* n : {"droPanel", "manualPanel", "overridePanel", "mainTabs"}) {
      if (auto* p = w_->findChild<QWidget*>(n)) widths += QString(" %1=%2").arg(n).arg(p->minimumSizeHint().width());
    }
    QVERIFY2(w_->minimumSizeHint().width() <= 1024,
             qPrintable(QString("window %1 px wide at least; parts:%2").arg(w_->minimumSizeHint().width()).arg(widths)));
    for (const QSize size : {QSize(1280, 1024), QSize(1024, 768)}) {
      w_->resize(size);
      QTRY_VERIFY(w_->width() <= size.width());
      QTest::qWait(300);  // trend samples
      QVERIFY2(drives->horizontalHeader()->length() <= drives->viewport()->width() + 1,
               qPrintable(QString("columns %1 px in %2 px").arg(drives->horizontalHeader()->length()).arg(drives->viewport()->width())));
      QVERIFY(!drives->horizontalScrollBar()->isVisible());
      shot(QString("drives-%1x%2").arg(size.width()).arg(size.height()));
    }
    QVERIFY(drives->horizontalHeaderItem(4)->text().contains("(mm)"));
    QVERIFY(drives->horizontalHeaderItem(6)->text().contains("mm/s"));
    bool decoded = false;
    for (int r = 0; r < drives->rowCount(); ++r) {
      if (drives->item(r, 2) && drives->item(r, 2)->text().contains(" SO")) decoded = true;
    }
    QVERIFY2(decoded, "no decoded statusword on the drive page");
    QVERIFY(w_->findChild<QLabel*>("driveStatuswordDetail")->text().contains("switched on"));
    for (const char* name : {"trendFollowingError", "trendTorque", "trendVelocity"}) {
      auto* view = w_->findChild<QChartView*>(name);
      QVERIFY2(view, name);
      QVERIFY2(!view->chart()->series().isEmpty(), name);
    }
    w_->resize(1280, 800);
  }

  // Override limits on the manual panel, with its meaning; the readouts
  // with units.
  void t13c_override_limits_and_readouts() {
    auto* b = button("overrideLimitsButton");
    QVERIFY(b);
    QVERIFY(b->toolTip().contains("limit switch"));
    QTRY_VERIFY_WITH_TIMEOUT(b->isEnabled(), 10000);
    click("overrideLimitsButton");
    QTRY_VERIFY_WITH_TIMEOUT(
        [&]() {
          const ipc::Status s = st();
          for (int j = 0; j < s.motion.joints; ++j) {
            if (s.joints[j].override_limits) return true;
          }
          return false;
        }(),
        5000);
    QTRY_VERIFY(b->isChecked());
    shot("override-limits");
    auto* effective = w_->findChild<QLabel*>("effectiveFeed");
    QVERIFY(effective);
    QVERIFY(effective->text().contains("mm/min"));
    QVERIFY(effective->text().contains("actual"));
  }

  // Machine Z where the simulated setter trips: table Z -100 plus the Z
  // drive's offset between table and joint position (as
  // Cia402SimMill.ProbingTakesTheDrivesLatchedPosition).
  double setter_contact_z() {
    const double fb = std::stod(hal("getp joint.2.pos-fb"));
    const double table = std::stod(hal("getp cia402-sim.1.node.03.table-position"));
    return -100 + fb - table;
  }

  // The tool-length routine's G-code (hmi/probing) run line by line through
  // the `cnc mdi` command-line client against the simulated tool setter;
  // the measured length goes into the tool table.
  void t13d_tool_length_routine_through_cnc_mdi() {
    const double contact = setter_contact_z();
    const ini::IniFile ini = ini::IniFile::load(run_ / "sim.ini");
    const probing::Settings settings = probing::Settings::from_ini(ini);
    QVERIFY(settings.setter);
    probing::Start start;
    start.position = st().motion.position;
    start.tool_in_spindle = st().io.tool_in_spindle;
    probing::Routine routine(settings, probing::Request{.kind = probing::Kind::ToolLength, .tool = 2}, start);
    const auto cnc = [&](const QStringList& args) {
      QProcess p;
      p.start(QString(CNC_BINARY_DIR) + "/bin/cnc", QStringList{"-i", QString::fromStdString(instance_), "--timeout", "60"} + args);
      if (!p.waitForFinished(90000)) return QString("cnc did not finish");
      return p.exitCode() == 0 ? QString() : QString::fromUtf8(p.readAllStandardError());
    };
    QCOMPARE(cnc({"mode", "mdi"}), QString());
    int stages = 0;
    while (!routine.done()) {
      for (const auto& line : routine.stage().lines) {
        QCOMPARE(cnc({"mdi", QString::fromStdString(line)}), QString());
      }
      const ipc::Status s = st();
      routine.completed(s.motion.probe_tripped, s.motion.probed_position);
      ++stages;
    }
    QVERIFY2(!routine.failed(), routine.error().c_str());
    QCOMPARE(stages, 3);  // to the setter, probe, result
    const double expected = contact + 118;
    qInfo("tool length through cnc mdi: %.4f, setter contact + 118: %.4f, difference %.2f um", routine.result().tool_length,
          expected, (routine.result().tool_length - expected) * 1000);
    QVERIFY2(std::fabs(routine.result().tool_length - expected) < 0.005,
             qPrintable(QString("length %1, expected %2").arg(routine.result().tool_length).arg(expected)));
    QTRY_VERIFY_WITH_TIMEOUT(
        [&]() {
          const auto t = tooltable::ToolTable::load(run_ / "tool.tbl", tooltable::ChangerKind::NonRandom);
          const auto idx = t.find_tool(2);
          return idx && std::fabs(t.at(*idx).offset[2] - routine.result().tool_length) < 1e-3;
        }(),
        10000);
    QVERIFY(near(st().motion.position[2], 0));  // back at the safe height
  }

  // The Probe page: tool length on the setter, a probe that finds nothing
  // (the routine fails, saying which move) and touch-off into a coordinate
  // system that is not the active one.
  void t13e_probe_page() {
    show_tab("probePage");
    auto* page = w_->findChild<QWidget*>("probePage");
    QVERIFY(page);
    QVERIFY(w_->findChild<QLabel*>("probeSettings")->text().contains("Tool setter at machine X 250"));
    shot("probe-page");
    const double contact = setter_contact_z();
    w_->findChild<QComboBox*>("probeRoutine")->setCurrentIndex(0);
    w_->findChild<QSpinBox*>("probeTool")->setValue(3);
    click("probeStart");
    auto* result = w_->findChild<QLabel*>("probeResult");
    QTRY_VERIFY_WITH_TIMEOUT(result->text().startsWith("T3 length") || result->text().startsWith("Failed"), 60000);
    QVERIFY2(result->text().startsWith("T3 length"), qPrintable(result->text()));
    const double length = result->text().section(' ', 2, 2).toDouble();
    QVERIFY2(std::fabs(length - (contact + 118)) < 0.005, qPrintable(result->text()));
    shot("probe-tool-length");
    // Edge X+ at the safe height: nothing to touch.
    w_->findChild<QComboBox*>("probeRoutine")->setCurrentIndex(1);
    click("probeStart");
    QTRY_VERIFY_WITH_TIMEOUT(result->text().startsWith("Failed"), 60000);
    QVERIFY2(result->text().contains("edge: probe X+: "), qPrintable(result->text()));
    QTRY_VERIFY_WITH_TIMEOUT(st().task.interp_state == ipc::InterpState::Idle, 10000);
    shot("probe-no-contact");
    // Touch-off: X reads 12.5 in G56 (G54 is active).
    QCOMPARE(st().task.g5x_index, 1);
    const double x = st().motion.position[0];
    w_->findChild<QComboBox*>("touchAxis")->setCurrentIndex(0);
    w_->findChild<QComboBox*>("touchSystem")->setCurrentIndex(2);  // G56
    w_->findChild<QLineEdit*>("touchValue")->setText("12,5");
    click("touchOffButton");
    QTRY_VERIFY_WITH_TIMEOUT(std::fabs(read_work_offsets(run_ / "sim.var").g5x[2][0] - (x - 12.5)) < 1e-3, 10000);
    QCOMPARE(st().task.g5x_index, 1);  // still G54
    shot("probe-touch-off");
  }

  // The Scope page: X's commanded and actual position and following error
  // captured on a rising velocity command while X jogs; plotted, exported
  // as the controller's CSV.
  void t13f_scope_page_captures_a_jog() {
    show_tab("scopePage");
    w_->findChild<QLineEdit*>("scopePins")->setText("joint.0.pos-cmd, joint.0.pos-fb, joint.0.f-error");
    w_->findChild<QLineEdit*>("scopeTrigger")->setText("joint.0.vel-cmd");
    w_->findChild<QLineEdit*>("scopeLevel")->setText("1");
    w_->findChild<QSpinBox*>("scopeSamples")->setValue(1000);
    w_->findChild<QSpinBox*>("scopePre")->setValue(20);
    click("scopeRun");
    auto* state = w_->findChild<QLabel*>("scopeState");
    QTRY_VERIFY_WITH_TIMEOUT(state->text().startsWith("Scope waiting"), 10000);
    shot("scope-armed");
    mdi("G53 G1 X290 F1200");  // +X from the setter at X250: vel-cmd rises through 1
    QTRY_VERIFY_WITH_TIMEOUT(state->text().startsWith("Capture 1"), 20000);
    show_tab("scopePage");
    QVERIFY(wait_for([](const ipc::Status& s) { return s.task.interp_state == ipc::InterpState::Idle; }, 30000));
    auto* page = w_->findChild<ScopePage*>("scopePage");
    QVERIFY(page && page->last_capture());
    const auto& c = *page->last_capture();
    QCOMPARE(c.names, (std::vector<std::string>{"joint.0.pos-cmd", "joint.0.pos-fb", "joint.0.f-error", "joint.0.vel-cmd"}));
    QCOMPARE(c.time.size(), std::size_t(1000));
    QVERIFY(std::fabs(c.time.front() + 0.2) < 0.01);  // 200 of 1000 samples before the trigger, 1 ms apart
    QVERIFY(c.columns[3].back() > 1.0);              // the trigger: velocity up
    auto* view = w_->findChild<QChartView*>("scopeChart");
    QCOMPARE(view->chart()->series().size(), 4);
    shot("scope-capture");
    const QString csv = dir_.path() + "/scope-export.csv";
    QVERIFY(page->export_csv(csv));
    QFile f(csv);
    QVERIFY(f.open(QIODevice::ReadOnly));
    QVERIFY(f.readLine().startsWith("time_s,joint.0.pos-cmd,joint.0.pos-fb,joint.0.f-error,joint.0.vel-cmd"));
  }

  void t14_estop() {
    click("estopButton");
    QVERIFY(wait_for([](const ipc::Status& s) { return s.task.state == ipc::TaskState::Estop && !s.motion.enabled; }, 10000));
    QTRY_COMPARE(button("estopButton")->text(), QString("E-STOP\nRESET"));
    // Nothing commanded is shown as in force after the E-stop.
    QTRY_VERIFY(w_->findChild<QLabel*>("effectiveFeed")->text().startsWith("F – (machine off) · now 0 mm/min"));
    shot("estop");
  }
};

QTEST_MAIN(E2eTests)
#include "e2e_tests.moc"
