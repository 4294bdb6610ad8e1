// The commissioning wizard under Xvfb (label gui), driven like a person on a
// simulated one-axis machine (sim/cia402/random_machine, seed 7): every
// page reached and screenshotted to <build>/commission-wizard-screenshots/
// (test artifacts, never committed), and a real run of steps 1-4 and 9
// through cnc-commission as the wizard's child processes: axis assigned,
// scaling set (the counts per mm shown live), a controller brought up, the
// direction test held to its end and the dial reading applied, a second
// test released early (SIGINT: aborted), the configuration's difference
// shown and written after the confirmation. Step 1's scan cannot reach the
// simulated drives from a child (a virtual bus is in-process): the page's
// scan is run to show its error, and the state gets its nodes from the same
// library scan run here, as tests/commission/random_machine_e2e_test.cpp
// does. Pages 5-8 run their subcommands, which may not exist in this build:
// the page must show a result, and the child's own error text when it
// fails.
#include <unistd.h>

#include <QApplication>
#include <QComboBox>
#include <QDir>
#include <QDoubleSpinBox>
#include <QLabel>
#include <QLineEdit>
#include <QListWidget>
#include <QMessageBox>
#include <QPlainTextEdit>
#include <QProgressBar>
#include <QPushButton>
#include <QScreen>
#include <QSpinBox>
#include <QTemporaryDir>
#include <QTextEdit>
#include <QTimer>
#include <QtCharts/QChartView>
#include <QtCharts/QLineSeries>
#include <QtTest>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "commission/scan.hpp"
#include "commission/state.hpp"
#include "commission/wizard/wizard_window.hpp"
#include "core/ini/ini_file.hpp"
#include "core/ipc/admin.hpp"
#include "hmi/link.hpp"
#include "sim/can/virtual_bus.hpp"
#include "sim/cia402/random_machine.hpp"
#include "sim/cia402/sim_config.hpp"
#include "sim/cia402/sim_host.hpp"

using namespace cnc;
using namespace cnc::commission;
using namespace cnc::commission::wizard;
namespace csim = cnc::cia402::sim;

class WizardGuiTests : public QObject {
  Q_OBJECT

  QTemporaryDir dir_{QDir::tempPath() + "/cnc-wizard-XXXXXX"};
  std::string instance_ = "wizard-gui-" + std::to_string(::getpid());
  std::filesystem::path m_;  // the machine folder: simulator files and the written configuration
  std::filesystem::path state_file_;
  csim::RandomMachine machine_;
  std::unique_ptr<WizardWindow> w_;
  QString shots_;
  int shot_ = 0;

  void shot(const QString& name) {
    for (int i = 0; i < 3; ++i) QTest::qWait(60);
    const QString file = QString("%1/wizard-%2-%3.png").arg(shots_).arg(++shot_, 2, 10, QChar('0')).arg(name);
    const QRect g = w_->frameGeometry();
    QPixmap pix = w_->QWidget::screen()->grabWindow(0, g.x(), g.y(), g.width(), g.height());
    if (pix.isNull()) pix = w_->grab();
    QVERIFY2(pix.save(file), qPrintable(file));
  }

  template <class T>
  T* find(const char* name) {
    T* x = w_->page(w_->current_step())->findChild<T*>(name);
    if (!x) x = w_->findChild<T*>(name);
    if (!x) qWarning("no widget %s", name);
    return x;
  }
  QString result() { return w_->page(w_->current_step())->result_label()->text(); }
  // Clicks a page's button and waits until its child has ended.
  void click_and_wait(const char* name, int ms = 60000) {
    auto* b = find<QPushButton>(name);
    QVERIFY2(b, name);
    QTest::mouseClick(b, Qt::LeftButton);
    wait_child(ms);
  }
  void wait_child(int ms = 60000) {
    StepPage* p = w_->page(w_->current_step());
    QTRY_VERIFY_WITH_TIMEOUT(!p->child().running() && !result().startsWith("running"), ms);
  }
  std::string hal(const std::string& line) {
    ipc::AdminClient admin(instance_);
    const auto r = admin.request(line);
    return r.ok ? r.text : "ERROR: " + r.text;
  }
  double table_position() { return std::stod(hal("getp cia402-sim.0.node.01.table-position")); }

  // Pages 5-8: each run ends with a result; a failure shows the child's words.
  void check_result_shown() {
    const QString r = result();
    QVERIFY2(!r.isEmpty() && !r.startsWith("running"), qPrintable(r));
    if (!r.startsWith("done")) QVERIFY2(r.contains("cnc-commission"), qPrintable(r));
  }

 private slots:
  void initTestCase() {
    QVERIFY(dir_.isValid());
    shots_ = QString(CNC_BINARY_DIR) + "/commission-wizard-screenshots";
    QDir().mkpath(shots_);
    for (const auto& old : QDir(shots_).entryList({"wizard-*.png"})) QFile::remove(shots_ + "/" + old);
    qputenv("CNC_INSTANCE", QByteArray::fromStdString(instance_));
    qputenv("CNC_NO_REALTIME", "1");
    m_ = std::filesystem::path(dir_.path().toStdString()) / "m";
    std::filesystem::create_directories(m_);
    state_file_ = std::filesystem::path(dir_.path().toStdString()) / "commission.json";
    machine_ = csim::make_random_machine(7, {1}, "virtual:wizard-" + std::to_string(::getpid()));
    std::ofstream(m_ / "sim-machine.ini") << csim::sim_ini(machine_);
    std::ofstream(m_ / "sim-machine.hal") << csim::sim_hal_load();
    std::ofstream(m_ / "sim-machine-run.hal") << csim::sim_hal_run();
    WizardOptions o;
    o.state_file = QString::fromStdString(state_file_.string());
    o.program = QString(CNC_BINARY_DIR) + "/bin/cnc-commission";
    o.config_dir = QString::fromStdString(m_.string());
    o.instance = QString::fromStdString(instance_);
    w_ = std::make_unique<WizardWindow>(o, std::make_unique<hmi::ClientLink>(instance_));
    w_->resize(1280, 900);
    w_->show();
    QVERIFY(QTest::qWaitForWindowExposed(w_.get()));
  }

  void cleanupTestCase() {
    w_.reset();
    QProcess p;
    p.start(QString(CNC_BINARY_DIR) + "/bin/cnc", {"shutdown"});
    p.waitForFinished(15000);
  }

  void t01_bus_page_shows_no_controller_and_the_scan_error() {
    QCOMPARE(w_->current_step(), 0);  // a fresh state starts at step 1
    QTRY_VERIFY(find<QLabel>("estopStatus")->text().contains("no controller"));
    QCOMPARE(find<QProgressBar>("stepsDone")->value(), 0);
    find<QLineEdit>("busInterface")->setText("virtual:nowhere");
    click_and_wait("scanButton");
    // The child's own words, not just a status.
    QVERIFY2(!result().startsWith("done"), qPrintable(result()));
    QVERIFY2(result().contains("cnc-commission:"), qPrintable(result()));
    shot("bus-scan-error");
  }

  void t02_bus_page_shows_the_scanned_drive() {
    // The scan of the simulated machine's bus, in this process.
    State s;
    {
      const auto cfg = csim::load_sim_config(ini::IniFile::load(m_ / "sim-machine.ini"), "CIA402_SIM");
      can::VirtualBusOptions vo;
      vo.manual_clock = false;
      auto vbus = can::VirtualBus::create(vo);
      auto host_port = vbus->open_port("host");
      auto scanner = vbus->open_port("scanner");
      csim::SimHost host(*host_port);
      for (const auto& n : cfg.nodes) host.add(n, vbus->open_port("node-" + std::to_string(n.node_id)));
      host.start();
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      ScanOptions so;
      so.timeout_ns = 1'000'000'000;
      so.last = 4;
      so.expected = {1};
      const ScanResult r = scan_canopen(*scanner, so);
      host.stop();
      QVERIFY2(!r.nodes.empty(), r.problems.empty() ? "no node" : r.problems[0].c_str());
      s.nodes = r.nodes;
    }
    s.interface = machine_.interface;
    s.ini_includes = {"sim-machine.ini"};
    s.hal_before_bus = {"sim-machine.hal"};
    s.hal_after_bus = {"sim-machine-run.hal"};
    save_state(s, state_file_);
    w_->reload_state();
    QCOMPARE(find<QListWidget>("foundDevices")->count(), 1);
    QVERIFY(w_->done()[0]);
    shot("bus-scanned");
  }

  void t03_axes_page_assigns_the_drive() {
    QTest::mouseClick(find<QPushButton>("nextButton"), Qt::LeftButton);
    QCOMPARE(w_->current_step(), 1);
    find<QSpinBox>("nodeId")->setValue(1);
    find<QSpinBox>("jointNumber")->setValue(0);
    click_and_wait("assignButton");
    QVERIFY2(result().startsWith("done"), qPrintable(result()));
    QCOMPARE(w_->state().axes.size(), std::size_t{1});
    QVERIFY(find<QListWidget>("axesList")->item(0)->text().startsWith("X: joint 0, node 1"));
    QVERIFY(w_->done()[1]);
    shot("axes");
  }

  void t04_scaling_page_shows_counts_per_mm_live() {
    QTest::mouseClick(find<QPushButton>("nextButton"), Qt::LeftButton);
    QCOMPARE(w_->current_step(), 2);
    find<QDoubleSpinBox>("screwLead")->setValue(4);
    const double counts = machine_.axes[0].encoder_counts;
    QVERIFY2(find<QLabel>("countsPerMm")->text().contains(QString::number(counts / 4, 'f', 3)),
             qPrintable(find<QLabel>("countsPerMm")->text()));
    find<QDoubleSpinBox>("screwLead")->setValue(5);  // the builder believes in 5 mm screws
    QVERIFY(find<QLabel>("countsPerMm")->text().contains(QString::number(counts / 5, 'f', 3)));
    click_and_wait("scalingButton");
    QVERIFY2(result().startsWith("done"), qPrintable(result()));
    QVERIFY(w_->done()[2]);
    shot("scaling");
  }

  void t05_direction_page_holds_to_run_and_applies_the_dial() {
    QTest::mouseClick(find<QPushButton>("nextButton"), Qt::LeftButton);
    QCOMPARE(w_->current_step(), 3);
    click_and_wait("bringUpButton");
    QVERIFY2(result().startsWith("done"), qPrintable(result() + "\n" + find<QPlainTextEdit>("stepOutput")->toPlainText()));
    QTRY_VERIFY_WITH_TIMEOUT(!find<QLabel>("estopStatus")->text().contains("no controller"), 10000);
    QTRY_VERIFY_WITH_TIMEOUT(find<QLabel>("drivesStatus")->text().contains("J0"), 10000);
    shot("controller-up");
    find<QDoubleSpinBox>("testDistance")->setValue(5);
    find<QDoubleSpinBox>("testVelocity")->setValue(5);
    const double before = table_position();
    auto* hold = find<QPushButton>("holdToRunButton");
    QTest::mousePress(hold, Qt::LeftButton);
    QTest::qWait(300);
    shot("direction-held");
    wait_child();  // held until the test ends by itself
    QTest::mouseRelease(hold, Qt::LeftButton);
    QVERIFY2(result().startsWith("done"), qPrintable(result() + "\n" + find<QPlainTextEdit>("stepOutput")->toPlainText()));
    QTest::qWait(200);
    const double dial = table_position() - before;
    find<QDoubleSpinBox>("dialValue")->setValue(dial);
    click_and_wait("dialButton");
    QVERIFY2(result().startsWith("done"), qPrintable(result()));
    QVERIFY(w_->done()[3]);
    const cnc::commission::Axis& a = *w_->state().axis('X');
    QCOMPARE(a.scaling.reverse, machine_.axes[0].motor_reversed);
    QVERIFY2(std::fabs(a.scaling.counts_per_mm() / machine_.axes[0].counts_per_mm() - 1) < 0.01,
             qPrintable(QString::number(a.scaling.counts_per_mm())));
    shot("direction-dial");

    // Released early: SIGINT, the run is aborted, the state keeps the last test.
    const std::string saved = to_json_text(w_->state());
    find<QDoubleSpinBox>("testDistance")->setValue(20);
    find<QDoubleSpinBox>("testVelocity")->setValue(1);
    QTest::mousePress(hold, Qt::LeftButton);
    QTest::qWait(2500);
    QTest::mouseRelease(hold, Qt::LeftButton);
    wait_child();
    QVERIFY2(result().startsWith("aborted"), qPrintable(result()));
    QCOMPARE(to_json_text(w_->state()), saved);
    QCOMPARE(QString::fromStdString(hal("getp cia402.0.drive.00.enabled")).trimmed(), QString("FALSE"));
    shot("direction-released");
  }

  void t05b_stop_button_aborts_a_running_step() {
    const std::string saved = to_json_text(w_->state());
    find<QDoubleSpinBox>("testDistance")->setValue(20);
    find<QDoubleSpinBox>("testVelocity")->setValue(1);
    // A held button, then Stop pressed (with the keyboard: the mouse holds the other button).
    auto* hold = find<QPushButton>("holdToRunButton");
    QTest::mousePress(hold, Qt::LeftButton);
    auto* stop = find<QPushButton>("stopButton");
    QTRY_VERIFY_WITH_TIMEOUT(stop->isEnabled(), 5000);
    QTest::qWait(1500);
    stop->click();
    wait_child();
    QTest::mouseRelease(hold, Qt::LeftButton);
    QVERIFY2(result().startsWith("aborted"), qPrintable(result()));
    QVERIFY(!stop->isEnabled());
    QCOMPARE(to_json_text(w_->state()), saved);
  }

  void t06_axes_page_identifies_the_drive_with_a_small_jog() {
    w_->show_step(1);
    const double before = table_position();
    const std::string saved = to_json_text(w_->state());
    click_and_wait("identifyButton");
    QVERIFY2(result().startsWith("done"), qPrintable(result()));
    QTest::qWait(200);
    // The controller runs the configuration brought up before the dial
    // corrected the scaling: the table moves about the identification jog.
    const double moved = std::fabs(table_position() - before);
    QVERIFY2(moved > 0.2 * kIdentifyDistance && moved < 5 * kIdentifyDistance, qPrintable(QString::number(moved)));
    QCOMPARE(to_json_text(w_->state()), saved);  // the jog ran on a copy of the state
    shot("axes-identified");
  }

  void t07_limits_page() {
    w_->show_step(4);
    QCOMPARE(w_->current_step(), 4);
    find<QDoubleSpinBox>("minLimit")->setValue(-20);
    find<QDoubleSpinBox>("maxLimit")->setValue(20);
    click_and_wait("limitsButton");
    QVERIFY2(result().startsWith("done"), qPrintable(result()));
    QVERIFY(find<QLabel>("limitsShown")->text().startsWith("limits -20 .. 20 mm"));
    click_and_wait("switchesButton", 120000);
    check_result_shown();
    shot("limits");
  }

  void t08_homing_page() {
    QTest::mouseClick(find<QPushButton>("nextButton"), Qt::LeftButton);
    QCOMPARE(w_->current_step(), 5);
    click_and_wait("methodsButton");
    check_result_shown();
    QVERIFY(find<QComboBox>("homingMethod")->count() >= 1);
    shot("homing");
  }

  void t09_tuning_page_plots_a_recording() {
    QTest::mouseClick(find<QPushButton>("nextButton"), Qt::LeftButton);
    QCOMPARE(w_->current_step(), 6);
    // A recording as the tune step writes it.
    const auto rec = m_ / "tune-X";
    std::filesystem::create_directories(rec);
    {
      std::ofstream out(rec / "test-1.csv");
      out << "time_s,command_mm,feedback_mm,ferror_mm,velocity_mm_s,torque_pct\n";
      for (int i = 0; i <= 200; ++i) {
        const double t = i * 0.005, v = 50 * std::sin(3.14159 * t);
        out << t << "," << t * 10 << "," << t * 10 - 0.002 * v / 50 << "," << 0.002 * v / 50 << "," << v << ","
            << 30 * std::cos(3.14159 * t) << "\n";
      }
    }
    w_->reload_state();
    QCOMPARE(find<QComboBox>("tuneRecordings")->count(), 1);
    auto* chart = find<QChartView>("ferrorChart");
    QCOMPARE(static_cast<QLineSeries*>(chart->chart()->series().at(0))->count(), 201);
    click_and_wait("tuneButton", 300000);
    check_result_shown();
    shot("tuning");
  }

  void t10_compensation_page() {
    QTest::mouseClick(find<QPushButton>("nextButton"), Qt::LeftButton);
    QCOMPARE(w_->current_step(), 7);
    find<QPlainTextEdit>("compValues")->setPlainText("2\n4, -1.5");
    click_and_wait("compMeasurementsButton");
    check_result_shown();
    find<QLineEdit>("compCsv")->setText("/tmp/laser.csv");
    click_and_wait("compMeasurementsButton");  // both: refused before anything starts
    QVERIFY2(result().contains("not both"), qPrintable(result()));
    find<QLineEdit>("compCsv")->clear();
    shot("compensation");
  }

  void t11_write_page_shows_the_difference_and_writes_after_confirmation() {
    QTest::mouseClick(find<QPushButton>("nextButton"), Qt::LeftButton);
    QCOMPARE(w_->current_step(), 8);
    QVERIFY(!find<QPushButton>("nextButton")->isEnabled());
    click_and_wait("diffButton");
    QVERIFY2(result().startsWith("done"), qPrintable(result()));
    QVERIFY(find<QTextEdit>("diffView")->toPlainText().contains("+[CIA402_DRIVE_0]"));
    QVERIFY(!std::filesystem::exists(m_ / "machine.ini"));
    shot("write-diff");
    bool asked = false;
    QTimer::singleShot(300, this, [&] {
      auto* box = qobject_cast<QMessageBox*>(QApplication::activeModalWidget());
      if (!box) return;
      asked = true;
      shot("write-confirm");
      box->button(QMessageBox::Yes)->click();
    });
    QTest::mouseClick(find<QPushButton>("writeButton"), Qt::LeftButton);
    QVERIFY(asked);
    wait_child();
    QVERIFY2(result().startsWith("done"), qPrintable(result() + "\n" + find<QPlainTextEdit>("stepOutput")->toPlainText()));
    QVERIFY(std::filesystem::exists(m_ / "machine.ini"));
    QVERIFY(w_->done()[8]);
    click_and_wait("backupButton");
    check_result_shown();
    shot("write-done");
  }

  void t12_progress_and_every_page() {
    const auto& d = w_->done();
    for (int i : {0, 1, 2, 3, 8}) QVERIFY2(d[static_cast<std::size_t>(i)], qPrintable(QString::number(i)));
    QVERIFY(find<QProgressBar>("stepsDone")->value() >= 5);
    for (int i = 0; i < kSteps; ++i) {
      w_->show_step(i);
      shot(QString("page-%1-%2").arg(i + 1).arg(QString(step_title(i)).toLower()));
    }
    w_->show_step(3);
    click_and_wait("shutdownButton");
    QVERIFY2(result().startsWith("done"), qPrintable(result()));
    QTRY_VERIFY_WITH_TIMEOUT(find<QLabel>("estopStatus")->text().contains("no controller"), 15000);
  }
};

QTEST_MAIN(WizardGuiTests)
#include "wizard_gui_test.moc"
