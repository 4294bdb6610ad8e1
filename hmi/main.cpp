// cnc-hmi: the Qt operator screen. Usage:
//   cnc-hmi [--instance NAME] [--geometry WxH] [--fullscreen] [--comma]
//           [--quit-after-startup] [--screenshot FILE] [MACHINE.ini]
// Without MACHINE.ini it opens the configuration picker: a dialog listing
// what `cnc-config list` lists; the choice is run by `cnc-config run`,
// which starts the controller and this screen on it (docs/install.md).
// It reads the INI file, connects to the controller of the instance
// (default $CNC_INSTANCE or "default") through the shared segment and
// shows its status; it starts without a controller and connects when one
// comes up.
#include <QApplication>
#include <QFileInfo>
#include <QInputDialog>
#include <QMessageBox>
#include <QProcess>
#include <QScreen>
#include <QTimer>
#include <unistd.h>

#include <cstdio>
#include <cerrno>
#include <cstring>
#include <functional>
#include <string>

#include "core/ini/ini_file.hpp"
#include "core/ipc/segment.hpp"
#include "core/util/time.hpp"
#include "hmi/main_window.hpp"

namespace {

const char* kStyle = R"(
QWidget { font-size: 13px; }
QPushButton { padding: 4px 8px; border: 1px solid #8a8a8a; border-radius: 3px; background: #e8e8e8; }
QPushButton:checked { background: #1f4e9c; color: white; }
QPushButton:pressed { background: #b0c8f0; }
QPushButton:disabled { color: #9a9a9a; background: #f0f0f0; border-color: #c8c8c8; }
QTabBar::tab { min-width: 72px; padding: 8px 10px; }
QSlider::groove:horizontal { height: 8px; background: #c8c8c8; border-radius: 4px; }
QSlider::handle:horizontal { width: 26px; margin: -10px 0; background: #1f4e9c; border-radius: 6px; }
QScrollBar:vertical { width: 18px; }
)";

// Calls `done` once, after the watched window's first paint event.
class FirstPaint : public QObject {
 public:
  FirstPaint(QObject* parent, std::function<void()> done) : QObject(parent), done_(std::move(done)) {}
  bool eventFilter(QObject* o, QEvent* e) override {
    if (e->type() == QEvent::Paint && done_) {
      QTimer::singleShot(0, this, [f = std::move(done_)]() { f(); });  // after the paint has finished
      done_ = nullptr;
    }
    return QObject::eventFilter(o, e);
  }

 private:
  std::function<void()> done_;
};

// Asked for (--help): on stdout, success. After a wrong call: on stderr, 2.
int usage(bool asked = false) {
  std::fprintf(asked ? stdout : stderr,
               "usage: cnc-hmi [--instance NAME] [--geometry WxH] [--fullscreen] [--comma]\n"
               "               [--quit-after-startup] [--screenshot FILE] [MACHINE.ini]\n"
               "  Without MACHINE.ini: a dialog to pick a configuration (cnc-config).\n");
  return asked ? 0 : 2;
}

// cnc-config beside this program (build/bin, /usr/bin), else on PATH.
QString cnc_config_program() {
  const QString beside = QCoreApplication::applicationDirPath() + "/cnc-config";
  return QFileInfo(beside).isExecutable() ? beside : QString("cnc-config");
}

// The picker: the configurations `cnc-config list --names` prints (lines
// "NAME KIND INI"), one chosen in a dialog and handed to `cnc-config run`,
// which copies a sample first and starts the controller and the screen.
// Returns only when nothing was run (the exit status).
int pick_configuration() {
  const QString program = cnc_config_program();
  QProcess list;
  list.start(program, {"list", "--names"});
  if (!list.waitForFinished(10000) || list.exitStatus() != QProcess::NormalExit || list.exitCode() != 0) {
    const QString why = list.error() == QProcess::FailedToStart
                            ? program + " did not start (is the package cnc installed?)"
                            : QString::fromLocal8Bit(list.readAllStandardError()).trimmed();
    QMessageBox::critical(nullptr, "cnc-hmi", "No configuration to choose from: " + why);
    return 1;
  }
  QStringList items, names;
  for (const QString& line : QString::fromLocal8Bit(list.readAllStandardOutput()).split('\n', Qt::SkipEmptyParts)) {
    const QStringList f = line.split(' ');
    if (f.size() < 3) continue;
    names << f[0];
    items << f[0] + (f[1] == "sample" ? "   (sample: copied to ~/cnc/configs first)" : "   (yours)");
  }
  bool ok = false;
  const QString chosen = QInputDialog::getItem(nullptr, "cnc-hmi: choose a machine configuration",
                                               "Configurations (yours in ~/cnc/configs, then the samples):", items,
                                               0, false, &ok);
  if (!ok) return 0;
  const std::string name = names[static_cast<int>(items.indexOf(chosen))].toStdString();
  const std::string prog = program.toStdString();
  ::execlp(prog.c_str(), prog.c_str(), "run", name.c_str(), static_cast<char*>(nullptr));
  QMessageBox::critical(nullptr, "cnc-hmi", QString("cannot run ") + program + ": " + std::strerror(errno));
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  const int64_t t0 = cnc::monotonic_ns();
  std::string instance = cnc::ipc::default_instance();
  std::string ini_path, screenshot;
  int width = 1280, height = 800;
  bool fullscreen = false, quit_after_startup = false, comma = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if ((a == "--instance" || a == "-i") && i + 1 < argc) instance = argv[++i];
    else if (a == "--geometry" && i + 1 < argc && std::sscanf(argv[i + 1], "%dx%d", &width, &height) == 2) ++i;
    else if (a == "--fullscreen") fullscreen = true;
    else if (a == "--comma") comma = true;
    else if (a == "--quit-after-startup") quit_after_startup = true;
    else if (a == "--screenshot" && i + 1 < argc) screenshot = argv[++i];
    else if (a == "--help" || a == "-h") return usage(true);
    else if (!a.empty() && a[0] != '-' && ini_path.empty()) ini_path = a;
    else {
      std::fprintf(stderr, "cnc-hmi: unknown argument %s\n", a.c_str());
      return usage();
    }
  }
  QApplication app(argc, argv);
  if (ini_path.empty()) return pick_configuration();

  QApplication::setStyle("Fusion");
  app.setStyleSheet(kStyle);
  cnc::hmi::HmiConfig config;
  cnc::hmi::UserDialogConfig dialogs;
  try {
    const cnc::ini::IniFile ini = cnc::ini::IniFile::load(ini_path);
    config = cnc::hmi::HmiConfig::from_ini(ini);
    dialogs = cnc::hmi::UserDialogConfig::from_ini(ini);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cnc-hmi: %s\n", e.what());
    return 1;
  }
  cnc::hmi::MainWindow::Options options;
  options.number_comma = comma;
  cnc::hmi::MainWindow window(std::move(config), std::move(dialogs), std::make_unique<cnc::hmi::ClientLink>(instance),
                              cnc::hmi::make_admin_executor(instance), options);
  window.resize(width, height);
  if (fullscreen) window.showFullScreen();
  else window.show();

  if (quit_after_startup || !screenshot.empty()) {
    // After the window's first paint (and, for a screenshot, a few cycles).
    auto* watch = new FirstPaint(&window, [&, t0]() {
      const double ms = static_cast<double>(cnc::monotonic_ns() - t0) / 1e6;
      QTimer::singleShot(screenshot.empty() ? 0 : 1500, &window, [&, ms]() {
        if (!screenshot.empty()) window.grab().save(QString::fromStdString(screenshot));
        std::printf("cnc-hmi: first frame %.0f ms after start\n", ms);
        std::fflush(stdout);
        QApplication::quit();
      });
    });
    window.installEventFilter(watch);
  }
  return QApplication::exec();
}
