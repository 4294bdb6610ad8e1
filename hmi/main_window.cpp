#include <stdexcept>

#include "hmi/main_window.hpp"

#include <QApplication>
#include <QCloseEvent>
#include <QDir>
#include <QFileDialog>
#include <QFileInfo>
#include <QHBoxLayout>
#include <QIcon>
#include <QKeyEvent>
#include <QLabel>
#include <QMessageBox>
#include <QProcess>
#include <QPushButton>
#include <QScrollArea>
#include <QScrollBar>
#include <QSpinBox>
#include <QTabBar>
#include <QSplitter>
#include <QTabWidget>
#include <QTimer>
#include <QVBoxLayout>
#include <cmath>
#include <cstdio>

#include "core/util/atomic_file.hpp"
#include "core/util/strings.hpp"
#include "core/util/time.hpp"
#include "hmi/panels.hpp"
#include "hmi/positions.hpp"
#include "hmi/preview_path.hpp"
#include "hmi/preview_widget.hpp"
#include "hmi/program_text.hpp"
#include "hmi/readouts.hpp"

namespace cnc::hmi {
namespace {

constexpr int kTagSetup = 1;
constexpr int kTagPostgui = 2;
constexpr int kTagSetr = 3;

// A tab for an EMBED_TAB_COMMAND: a native window whose id replaces {XID}
// in the command, so the program can put its window inside (XEmbed style).
class EmbeddedPanel : public QWidget {
 public:
  EmbeddedPanel(const ::cnc::hmi::EmbedTab& cfg, const QString& dir, std::vector<QProcess*>& processes, Screen& s, QWidget* parent)
      : QWidget(parent), cfg_(cfg), dir_(dir), processes_(processes), s_(s) {
    auto* v = new QVBoxLayout(this);
    v->setContentsMargins(0, 0, 0, 0);
    container_ = new QWidget(this);
    container_->setObjectName("embedContainer");
    container_->setAttribute(Qt::WA_NativeWindow);
    note_ = new QLabel(this);
    v->addWidget(note_);
    v->addWidget(container_, 1);
  }

 protected:
  void showEvent(QShowEvent* e) override {
    QWidget::showEvent(e);
    if (started_) return;
    started_ = true;
    QString cmd = QString::fromStdString(cfg_.command);
    const bool embeds = cmd.contains("{XID}");
    cmd.replace("{XID}", QString::number(container_->winId()));
    auto* p = new QProcess(this);
    p->setWorkingDirectory(dir_);
    p->setProcessChannelMode(QProcess::MergedChannels);
    processes_.push_back(p);
    QObject::connect(p, &QProcess::finished, this, [this, p](int code, QProcess::ExitStatus) {
      const QString out = QString::fromLocal8Bit(p->readAll()).trimmed();
      note_->setText(QString("%1 exited (code %2)").arg(QString::fromStdString(cfg_.command)).arg(code));
      s_.log(code ? LogLevel::Warning : LogLevel::Info,
             "embedded tab \"" + cfg_.name + "\" exited with code " + std::to_string(code) +
                 (out.isEmpty() ? "" : ": " + out.left(400).toStdString()));
    });
    p->start("/bin/sh", {"-c", cmd});
    note_->setText(embeds ? QString() : QString("%1 runs in its own window (no {XID} in EMBED_TAB_COMMAND)").arg(cmd));
    note_->setVisible(!embeds);
    s_.log(LogLevel::Info, "embedded tab \"" + cfg_.name + "\": " + cmd.toStdString());
  }

 private:
  ::cnc::hmi::EmbedTab cfg_;
  QString dir_;
  std::vector<QProcess*>& processes_;
  Screen& s_;
  QWidget* container_;
  QLabel* note_;
  bool started_ = false;
};

int64_t realtime() { return realtime_ns(); }

// Jog keys: (axis, direction) or axis -1.
std::pair<int, int> jog_key(int key, bool lathe, bool back_tool) {
  if (lathe) {
    switch (key) {
      case Qt::Key_Left: return {2, -1};
      case Qt::Key_Right: return {2, 1};
      case Qt::Key_Up: return {0, back_tool ? 1 : -1};
      case Qt::Key_Down: return {0, back_tool ? -1 : 1};
      default: break;
    }
  } else {
    switch (key) {
      case Qt::Key_Left: return {0, -1};
      case Qt::Key_Right: return {0, 1};
      case Qt::Key_Up: return {1, 1};
      case Qt::Key_Down: return {1, -1};
      case Qt::Key_PageUp: return {2, 1};
      case Qt::Key_PageDown: return {2, -1};
      default: break;
    }
  }
  switch (key) {
    case Qt::Key_BracketLeft: return {3, -1};
    case Qt::Key_BracketRight: return {3, 1};
    default: return {-1, 0};
  }
}

}  // namespace

MainWindow::MainWindow(HmiConfig config, UserDialogConfig dialogs, std::unique_ptr<MachineLink> link, HalExecutor hal,
                       Options options)
    : config_(std::move(config)),
      options_(options),
      link_(std::move(link)),
      tracker_(*link_),
      jog_([this](const ipc::Command& c) {
        const char* what = c.type == ipc::CommandType::JogStop ? "jog stop" : "jog";
        tracker_.send(c, what);
      }),
      history_(config_.mdi_history_file),
      screen_(config_, tracker_, jog_, alarms_),
      dialogs_(std::move(dialogs)) {
  screen_.numbers = NumberFormat(options_.number_comma ? ',' : '.');
  screen_.now_ns = realtime;
  screen_.show_actual = config_.position_feedback_actual;
  if (!config_.log_file.empty()) {
    log_file_ = std::fopen(config_.log_file.c_str(), "a");
  }
  alarms_.acknowledge_in_controller = [this](uint32_t id) {
    screen_.send(ipc::commands::acknowledge_alarm(id), id ? "acknowledge alarm " + std::to_string(id) : "acknowledge all alarms");
  };
  alarms_.on_log = [this](const LogEntry& e) {
    log_to_file(e);
    if (alarms_page_) alarms_page_->append_log(e);
    if (strip_ && (e.level != LogLevel::Info || e.source == "screen")) {
      strip_->show_message(QString::fromStdString(AlarmLog::format_time(e.time_ns) + "  " + e.text),
                           e.level == LogLevel::Error || e.level == LogLevel::Warning);
    }
  };
  tracker_.set_reject_sink([this](const std::string& what, const std::string& reason) {
    alarms_.post_local(LogLevel::Warning, "command", what + " rejected: " + reason, realtime());
  });
  std::vector<JogController::AxisInfo> axes;
  for (const auto& a : config_.axes) {
    int joint = -1, count = 0;
    for (const auto& j : config_.joints) {
      if (j.axis == a.index) {
        joint = j.index;
        ++count;
      }
    }
    axes.push_back(JogController::AxisInfo{a.index, a.angular, count == 1 ? joint : -1});
  }
  jog_.set_axes(axes);
  jog_.set_increments(config_.increments, config_.angular_increments);
  if (!history_.load()) alarms_.post_local(LogLevel::Warning, "screen", "MDI history: " + history_.error(), realtime());
  if (hal && options_.hal) {
    hal_ = std::make_unique<HalChannel>(std::move(hal));
    connect(hal_.get(), &HalChannel::replied, this, &MainWindow::hal_replied);
    connect(hal_.get(), &HalChannel::polled, this, [this](const QString& text) {
      apply_dialog_actions(dialogs_.update(parse_show_pin(text.toStdString())));
    });
  }
  build();
  for (const auto& w : config_.warnings) alarms_.post_local(LogLevel::Warning, "config", w, realtime());
  for (const auto& w : dialogs_.config().warnings) alarms_.post_local(LogLevel::Warning, "config", w, realtime());
  qApp->installEventFilter(this);
  connect(qApp, &QApplication::focusChanged, this, [this](QWidget*, QWidget* now) {
    jog_.set_text_input_focus(ui::is_text_input(now));
  });
  connect(qApp, &QGuiApplication::applicationStateChanged, this, [this](Qt::ApplicationState st) {
    if (st != Qt::ApplicationActive) jog_.focus_lost();
  });
  timer_ = new QTimer(this);
  timer_->setTimerType(Qt::CoarseTimer);
  connect(timer_, &QTimer::timeout, this, &MainWindow::tick);
  backplot_timer_ = new QTimer(this);
  backplot_timer_->setInterval(std::min(config_.cycle_time_ms, 25));
  connect(backplot_timer_, &QTimer::timeout, this, &MainWindow::sample_backplot);
  if (options_.start_timer) {
    timer_->start(config_.cycle_time_ms);
    QTimer::singleShot(0, this, &MainWindow::tick);
  }
  if (!config_.open_file.empty()) {
    QTimer::singleShot(0, this, [this]() {
      if (connected_ && screen_.status.task.file.empty()) open_program(QString::fromStdString(config_.open_file.string()));
    });
  }
}

MainWindow::~MainWindow() {
  qApp->removeEventFilter(this);
  if (preview_cancel_) preview_cancel_->store(true);
  if (preview_thread_.joinable()) preview_thread_.join();
  for (QProcess* p : embedded_) {
    p->disconnect();
    if (p->state() != QProcess::NotRunning) {
      p->terminate();
      if (!p->waitForFinished(1000)) p->kill();
    }
  }
  if (filter_) filter_->disconnect();
  if (estimate_) {
    estimate_->disconnect();
    estimate_->kill();
    estimate_->waitForFinished(1000);
  }
  alarms_.on_log = nullptr;
  if (log_file_) std::fclose(log_file_);
}

void MainWindow::build() {
  setWindowTitle(QString::fromStdString(config_.title));
  if (!config_.icon.empty()) setWindowIcon(QIcon(QString::fromStdString(config_.icon.string())));
  setMinimumSize(1000, 700);
  auto* central = new QWidget(this);
  central->setFocusPolicy(Qt::ClickFocus);  // a tap on the background takes the keys back for jogging
  auto* v = new QVBoxLayout(central);
  v->setContentsMargins(2, 2, 2, 2);
  v->setSpacing(2);
  strip_ = new StatusStrip(screen_, central);
  v->addWidget(strip_);

  auto* split = new QSplitter(Qt::Horizontal, central);
  split->setObjectName("mainSplitter");
  split->setChildrenCollapsible(false);
  auto* left = new QWidget(split);
  auto* lv = new QVBoxLayout(left);
  lv->setContentsMargins(0, 0, 0, 0);
  dro_ = new DroPanel(screen_, left);
  manual_ = new ManualPanel(screen_, left);
  overrides_ = new OverridePanel(screen_, left);
  lv->addWidget(dro_);
  lv->addWidget(manual_);
  lv->addWidget(overrides_);
  lv->addStretch(1);
  auto* scroll = new QScrollArea(split);
  scroll->setWidget(left);
  scroll->setWidgetResizable(true);
  scroll->setHorizontalScrollBarPolicy(Qt::ScrollBarAlwaysOff);
  scroll->setMinimumWidth(left->minimumSizeHint().width() + scroll->verticalScrollBar()->sizeHint().width() + 4);
  scroll->setFrameShape(QFrame::NoFrame);

  tabs_ = new QTabWidget(split);
  tabs_->setObjectName("mainTabs");
  tabs_->tabBar()->setMinimumHeight(ui::kTouch - 6);
  // Program page: preview over the program text.
  program_page_ = new QWidget(tabs_);
  program_page_->setObjectName("programPage");
  auto* pv = new QVBoxLayout(program_page_);
  pv->setContentsMargins(2, 2, 2, 2);
  auto* views = new QHBoxLayout();
  preview_ = new PreviewWidget(program_page_);
  preview_->set_lathe(config_.lathe, config_.back_tool_lathe);
  {
    Pose lo, hi;
    for (int a = 0; a < 3; ++a) {
      lo[a] = -1e9;
      hi[a] = 1e9;
    }
    for (const auto& a : config_.axes) {
      if (a.index < 3) {
        lo[a.index] = a.min_limit;
        hi[a.index] = a.max_limit;
      }
    }
    bool finite = true;
    for (int a = 0; a < 3; ++a) finite = finite && std::fabs(lo[a]) < 1e8 && std::fabs(hi[a]) < 1e8;
    if (finite) preview_->set_limits(lo, hi);
  }
  const auto view_button = [&](const QString& text, const char* name, auto fn) {
    auto* b = ui::button(text, name, program_page_);
    b->setFixedWidth(std::max(ui::kTouch + 4, b->fontMetrics().horizontalAdvance(text) + 20));
    connect(b, &QPushButton::clicked, this, fn);
    views->addWidget(b);
  };
  if (config_.lathe) {
    view_button("Lathe", "viewLathe", [this]() { preview_->set_view(PreviewWidget::View::Lathe); });
    view_button("P", "viewP", [this]() { preview_->set_view(PreviewWidget::View::Perspective); });
  } else {
    view_button("P", "viewP", [this]() { preview_->set_view(PreviewWidget::View::Perspective); });
    view_button("X", "viewX", [this]() { preview_->set_view(PreviewWidget::View::X); });
    view_button("Y", "viewY", [this]() { preview_->set_view(PreviewWidget::View::Y); });
    view_button("Z", "viewZ", [this]() { preview_->set_view(PreviewWidget::View::Z); });
  }
  view_button("+", "zoomIn", [this]() { preview_->zoom(1.25); });
  view_button("−", "zoomOut", [this]() { preview_->zoom(0.8); });
  view_button("Fit", "zoomFit", [this]() { preview_->fit(); });
  view_button("Clear", "clearBackplot", [this]() { preview_->clear_backplot(); });
  views->addStretch(1);
  pv->addLayout(views);
  auto* psplit = new QSplitter(Qt::Vertical, program_page_);
  psplit->addWidget(preview_);
  program_text_ = new ProgramText(psplit);
  psplit->addWidget(program_text_);
  psplit->setStretchFactor(0, 3);
  psplit->setStretchFactor(1, 2);
  pv->addWidget(psplit, 1);
  tabs_->addTab(program_page_, "Program");
  bar_ = new ProgramBar(screen_, central);
  pv->addWidget(bar_->line_row());
  mdi_ = new MdiPage(screen_, history_, tabs_);
  tabs_->addTab(mdi_, "MDI");
  tools_ = new ToolPage(screen_, tabs_);
  tabs_->addTab(tools_, "Tools");
  offsets_ = new OffsetsPage(screen_, tabs_);
  tabs_->addTab(offsets_, "Offsets");
  alarms_page_ = new AlarmsPage(screen_, tabs_);
  tabs_->addTab(alarms_page_, "Alarms / log");
  drives_ = new DrivesPage(screen_, tabs_);
  tabs_->addTab(drives_, "Drives");
  probe_ = new ProbePage(screen_, tabs_);
  tabs_->addTab(probe_, "Probe");
  scope_ = new ScopePage(screen_, hal_.get(), tabs_);
  tabs_->addTab(scope_, "Scope");
  if (options_.embed_tabs) {
    const QString dir = QString::fromStdString(config_.ini_path.parent_path().string());
    for (const auto& e : config_.embed_tabs) {
      if (!e.location.empty() && e.location != "tabs" && e.location != "main") {
        alarms_.post_local(LogLevel::Warning, "config",
                           "EMBED_TAB_LOCATION = " + e.location + ": this screen puts embedded panels in its main tabs", realtime());
      }
      tabs_->addTab(new EmbeddedPanel(e, dir, embedded_, screen_, tabs_), QString::fromStdString(e.name));
    }
  }
  connect(tabs_, &QTabWidget::currentChanged, this, [this](int) { refresh_pages(); });
  split->addWidget(scroll);
  split->addWidget(tabs_);
  split->setStretchFactor(0, 0);
  split->setStretchFactor(1, 1);
  v->addWidget(split, 1);
  v->addWidget(bar_);
  setCentralWidget(central);

  connect(strip_, &StatusStrip::alarmsClicked, this, [this]() { tabs_->setCurrentWidget(alarms_page_); });
  connect(bar_, &ProgramBar::openRequested, this, &MainWindow::choose_program);
  connect(bar_, &ProgramBar::reloadRequested, this, [this]() {
    if (!screen_.status.task.file.empty()) open_program(ui::qs(screen_.status.task.file.view()));
  });
  connect(bar_, &ProgramBar::runFromLineRequested, this, &MainWindow::request_run_from_line);
  connect(program_text_, &ProgramText::lineSelected, this, [this](int line) { bar_->start_line()->setValue(line); });
  // Replay what was logged before the pages existed.
  for (const auto& e : alarms_.log()) alarms_page_->append_log(e);
}

void MainWindow::log_to_file(const LogEntry& e) {
  if (!log_file_) return;
  std::fprintf(log_file_, "%s %-8s [%s] %s\n", AlarmLog::format_time(e.time_ns, true).c_str(), to_string(e.level),
               e.source.c_str(), e.text.c_str());
  std::fflush(log_file_);
}

// ------------------------------------------------------------ the cycle

void MainWindow::tick() {
  ipc::Status s;
  std::string why;
  const bool ok = link_->read_status(s, why);
  const bool just_connected = ok && !connected_;
  if (ok != connected_) {
    connected_ = ok;
    screen_.connected = ok;
    jog_.set_connected(ok);
    if (ok) {
      alarms_.post_local(LogLevel::Info, "screen", "connected to the controller", realtime());
    } else if (ever_connected_ || why != last_disconnect_reason_) {
      alarms_.post_local(ever_connected_ ? LogLevel::Error : LogLevel::Warning, "screen", "no controller: " + why, realtime());
    }
    last_disconnect_reason_ = why;
  }
  if (ok) {
    screen_.status = s;
    screen_.liveness = link_->liveness(s);
    if (just_connected) on_connected();  // also after a controller restart
    ever_connected_ = true;
    Message m;
    uint64_t lost = 0;
    while (link_->next_message(m, lost)) {
      if (lost) {
        alarms_.post_local(LogLevel::Warning, "screen", std::to_string(lost) + " messages were lost (the screen fell behind)", realtime());
        lost = 0;
      }
      alarms_.post(m);
    }
    alarms_.update_controller(s.alarms);
    alarms_.update_drives(s, realtime());
    jog_.update(s);
    // A program opened by anyone (this screen, the CLI) is shown.
    const std::string file(s.task.file.view());
    if (file != shown_file_) {
      shown_file_ = file;
      load_program(QString::fromStdString(file));
    }
    // A program starting in AUTO brings its page to the front.
    if (last_interp_ == ipc::InterpState::Idle && s.task.interp_state != ipc::InterpState::Idle &&
        s.task.mode == ipc::TaskMode::Auto) {
      tabs_->setCurrentWidget(program_page_);
      preview_->clear_backplot();  // the plot shows this run
    }
    // Tools and offsets may change under a program (G10, M6): re-read at its end.
    if (last_interp_ != ipc::InterpState::Idle && s.task.interp_state == ipc::InterpState::Idle) {
      tools_->reload_file();
      offsets_->reload_file();
    }
    last_interp_ = s.task.interp_state;
    // The preview depends on offsets, tool and the start position: redo it
    // when they change while nothing runs.
    if (!shown_file_.empty() && s.task.interp_state == ipc::InterpState::Idle) {
      char key[512];
      std::snprintf(key, sizeof key, "%d %.6f %.6f %.6f %.6f %.6f %.6f %.6f %d %d", s.task.g5x_index, s.task.g5x_offset[0],
                    s.task.g5x_offset[1], s.task.g5x_offset[2], s.task.g92_offset[0], s.task.g92_offset[1],
                    s.task.g92_offset[2], s.task.rotation_xy, s.io.tool_in_spindle, s.task.block_delete ? 1 : 0);
      if (!preview_key_.empty() && preview_key_ != key) start_preview(QString::fromStdString(shown_file_));
      preview_key_ = key;
    }
    const DroPositions d = dro_positions(s, screen_.show_actual);
    const double f = program_to_machine(s);
    Pose origin;
    for (int a = 0; a < 3; ++a) origin[a] = (s.task.g5x_offset[a] + s.task.g92_offset[a]) * f;
    preview_->set_origin(origin, true);
    preview_->set_tool(d.machine, d.valid, s.task.tool_offset[2] * f);
    preview_->set_executing_line(s.task.interp_state == ipc::InterpState::Idle ? 0 : s.task.current_line);
    program_text_->set_lines(s.task.interp_state == ipc::InterpState::Idle ? 0 : s.task.current_line,
                             s.task.interp_state == ipc::InterpState::Idle ? 0 : s.task.read_line);
    const bool moving = !s.motion.inpos || std::fabs(s.motion.current_vel) > 1e-9;
    if (moving && !backplot_timer_->isActive()) backplot_timer_->start();
    if (moving || backplot_timer_->isActive()) preview_->add_backplot(d.machine);
    preview_->flush();
    check_run_from_line();
  }
  tracker_.poll(monotonic_ns());
  overrides_->flush();
  strip_->refresh();
  dro_->refresh();
  manual_->refresh();
  overrides_->refresh();
  bar_->refresh();
  drives_->sample(static_cast<double>(monotonic_ns()) * 1e-9);
  probe_->refresh();  // a running routine goes on whichever page is shown
  refresh_pages();
}

void MainWindow::refresh_pages() {
  QWidget* current = tabs_->currentWidget();
  if (current == mdi_) mdi_->refresh();
  else if (current == tools_) tools_->refresh();
  else if (current == offsets_) offsets_->refresh();
  else if (current == drives_) drives_->refresh();
  if (current == scope_ || scope_->capturing()) scope_->refresh();
  if (alarms_.revision() != alarms_revision_) {
    alarms_revision_ = alarms_.revision();
    alarms_page_->refresh_alarms();
    strip_->refresh();
  }
}

void MainWindow::sample_backplot() {
  ipc::Status s;
  std::string why;
  if (!link_->read_status(s, why)) {
    backplot_timer_->stop();
    return;
  }
  const DroPositions d = dro_positions(s, screen_.show_actual);
  if (d.valid) preview_->add_backplot(d.machine);
  if (s.motion.inpos && std::fabs(s.motion.current_vel) < 1e-9) backplot_timer_->stop();
}

void MainWindow::on_connected() {
  tools_->reload_file();
  offsets_->reload_file();
  hal_setup();
}

// ------------------------------------------------------------ programs

void MainWindow::choose_program() {
  auto* dialog = new QFileDialog(this, "Open a program", QString::fromStdString(config_.program_prefix.string()));
  dialog->setObjectName("openDialog");
  dialog->setAttribute(Qt::WA_DeleteOnClose);
  dialog->setFileMode(QFileDialog::ExistingFile);
  dialog->setOption(QFileDialog::DontUseNativeDialog, true);
  QStringList filters;
  QStringList all;
  for (const auto& f : config_.program_filters) {
    QStringList globs;
    for (const auto& e : f.extensions) globs << "*." + QString::fromStdString(e);
    all << globs;
    filters << QString("%1 (%2)").arg(QString::fromStdString(f.description), globs.join(' '));
  }
  if (filters.size() > 1) filters.prepend(QString("All programs (%1)").arg(all.join(' ')));
  if (filters.isEmpty()) filters << "G-code (*.ngc *.nc *.tap)";
  filters << "All files (*)";
  dialog->setNameFilters(filters);
  dialog->resize(900, 600);
  connect(dialog, &QFileDialog::fileSelected, this, [this](const QString& f) { open_program(f); });
  dialog->open();
}

void MainWindow::open_program(const QString& path) {
  const QFileInfo info(path);
  const QString abs = info.absoluteFilePath();
  if (const FilterProgram* f = config_.filter_for(info.fileName().toStdString())) {
    run_filter(abs, *f);
    return;
  }
  ipc::Command cmd;
  try {
    cmd = commands::open(abs.toStdString());
  } catch (const std::invalid_argument& e) {
    screen_.log(LogLevel::Error, "open " + abs.toStdString() + ": not sent: " + e.what());
    return;
  }
  screen_.send(cmd, "open " + abs.toStdString(), [this, abs](const ipc::CommandResult& r) {
    if (r.state != ipc::CommandState::Done) return;
    screen_.log(LogLevel::Info, "opened " + abs.toStdString());
    shown_file_ = abs.toStdString();
    tabs_->setCurrentWidget(program_page_);  // the operator sees what was opened
    load_program(abs);  // also when the same file was opened again (reload)
  });
}

void MainWindow::run_filter(const QString& path, const FilterProgram& f) {
  if (filter_) {
    screen_.log(LogLevel::Warning, "a filter program is still running");
    return;
  }
  const QString dir = QDir::tempPath() + QString("/cnc-hmi-%1").arg(QCoreApplication::applicationPid());
  QDir().mkpath(dir);
  const QString out = dir + "/" + QFileInfo(path).completeBaseName() + ".ngc";
  filter_ = new QProcess(this);
  filter_->setStandardOutputFile(out);
  filter_->setWorkingDirectory(QFileInfo(path).absolutePath());
  auto* err = new QString();
  connect(filter_, &QProcess::readyReadStandardError, this, [this, err]() {
    const QString text = QString::fromLocal8Bit(filter_->readAllStandardError());
    for (const QString& line : text.split('\n')) {
      if (line.startsWith("FILTER_PROGRESS=")) strip_->set_filter_progress(line.mid(16).trimmed().toInt());
      else if (!line.trimmed().isEmpty()) *err += line + "\n";
    }
  });
  connect(filter_, &QProcess::finished, this, [this, out, path, err, f](int code, QProcess::ExitStatus st) {
    strip_->set_filter_progress(-1);
    filter_->deleteLater();
    filter_ = nullptr;
    const QString msg = err->trimmed();
    delete err;
    if (st != QProcess::NormalExit || code != 0) {
      screen_.log(LogLevel::Error, "filter " + f.program + " failed on " + path.toStdString() + " (exit " + std::to_string(code) +
                                       ")" + (msg.isEmpty() ? "" : ": " + msg.toStdString()));
      return;
    }
    screen_.log(LogLevel::Info, "filter " + f.program + ": " + path.toStdString() + " -> " + out.toStdString());
    open_program(out);
  });
  strip_->set_filter_progress(0);
  // The program is a command line (e.g. "python3" or "image-to-gcode -x"); the file is its last argument.
  QStringList args = QProcess::splitCommand(QString::fromStdString(f.program));
  const QString program = args.isEmpty() ? QString() : args.takeFirst();
  args << path;
  filter_->start(program, args);
}

void MainWindow::load_program(const QString& path) {
  if (path.isEmpty()) {
    program_text_->clear_program();
    preview_->clear_path();
    return;
  }
  QString error;
  if (!program_text_->load(path, config_.graphical_max_file_size > 0 ? config_.graphical_max_file_size : -1, error)) {
    screen_.log(LogLevel::Warning, "cannot show " + path.toStdString() + ": " + error.toStdString());
  }
  bar_->start_line()->setMaximum(std::max(1, program_text_->blockCount()));
  preview_->clear_backplot();
  start_preview(path);
}

void MainWindow::start_estimate(const QString& path) {
  const QString canonical = QFileInfo(path).canonicalFilePath();
  screen_.estimate_s = -1;
  screen_.estimate_file = canonical.toStdString();
  if (estimate_) {
    estimate_->disconnect();
    estimate_->kill();
    estimate_->waitForFinished(1000);
    estimate_->deleteLater();
    estimate_ = nullptr;
  }
  // cnc-estimate beside this program (build/bin, /usr/bin), else on PATH
  const QString beside = QCoreApplication::applicationDirPath() + "/cnc-estimate";
  const QString program = QFileInfo(beside).isExecutable() ? beside : QString("cnc-estimate");
  QStringList args{"--ini", QString::fromStdString(config_.ini_path.string())};
  if (connected_) {
    const auto& p = screen_.status.motion.position;
    args << "--start" << QString("%1,%2,%3").arg(p[0], 0, 'f', 6).arg(p[1], 0, 'f', 6).arg(p[2], 0, 'f', 6);
  }
  args << path;
  estimate_ = new QProcess(this);
  estimate_->setProcessChannelMode(QProcess::MergedChannels);
  const std::string file = screen_.estimate_file;
  connect(estimate_, &QProcess::finished, this, [this, file, path](int code, QProcess::ExitStatus st) {
    const std::string out = estimate_->readAll().toStdString();
    estimate_->deleteLater();
    estimate_ = nullptr;
    if (file != screen_.estimate_file) return;  // another program was opened since
    const std::optional<double> seconds =
        st == QProcess::NormalExit && code == 0 ? parse_estimate_output(out) : std::nullopt;
    if (seconds) {
      screen_.estimate_s = *seconds;
      return;
    }
    const std::string first = out.substr(0, out.find('\n'));
    screen_.log(LogLevel::Info, "no time estimate for " + path.toStdString() + ": " + (first.empty() ? "cnc-estimate failed" : first));
  });
  connect(estimate_, &QProcess::errorOccurred, this, [this, path](QProcess::ProcessError e) {
    if (e != QProcess::FailedToStart || estimate_ == nullptr) return;
    estimate_->deleteLater();
    estimate_ = nullptr;
    screen_.log(LogLevel::Info, "no time estimate for " + path.toStdString() + ": cnc-estimate could not be started");
  });
  estimate_->start(program, args);
}

void MainWindow::start_preview(const QString& path) {
  start_estimate(path);
  if (preview_cancel_) preview_cancel_->store(true);
  if (preview_thread_.joinable()) preview_thread_.join();
  const QFileInfo info(path);
  if (config_.graphical_max_file_size > 0 && info.size() > config_.graphical_max_file_size) {
    preview_->clear_path();
    preview_->set_status_text(QString("No preview: the file is larger than GRAPHICAL_MAX_FILE_SIZE (%1 MB)")
                                  .arg(config_.graphical_max_file_size / (1024 * 1024)));
    return;
  }
  PreviewInput in;
  in.program = path.toStdString();
  in.ini = config_.ini_path;
  in.start_machine = screen_.status.motion.position;
  in.tool_in_spindle = screen_.status.io.tool_in_spindle;
  in.block_delete = screen_.status.task.block_delete;
  // The soft limits in force are motion's (published in the status, run-time
  // changes included); the INI's only until the controller answers.
  for (const auto& a : config_.axes) {
    const ipc::AxisStatus& st = screen_.status.axes[a.index];
    const bool published = connected_ && st.min_position_limit < st.max_position_limit;
    in.limits.push_back(AxisLimit{a.index, published ? st.min_position_limit : a.min_limit,
                                  published ? st.max_position_limit : a.max_limit});
  }
  preview_cancel_ = std::make_shared<std::atomic<bool>>(false);
  const unsigned generation = ++preview_generation_;
  preview_running_ = true;
  preview_->set_status_text("Computing the preview…");
  QPointer<MainWindow> self(this);
  preview_thread_ = std::thread([self, in, cancel = preview_cancel_, generation]() {
    auto result = std::make_shared<const PreviewResult>(build_preview(in, cancel.get()));
    if (cancel->load()) return;
    QMetaObject::invokeMethod(qApp, [self, result, generation]() {
      if (self) self->preview_ready(result, generation);
    }, Qt::QueuedConnection);
  });
}

void MainWindow::preview_ready(std::shared_ptr<const PreviewResult> result, unsigned generation) {
  if (generation != preview_generation_) return;
  preview_running_ = false;
  preview_->set_status_text(QString());
  preview_->set_path(result);
  if (!result->error.empty()) {
    screen_.log(LogLevel::Warning, "preview: line " + std::to_string(result->error_line) + ": " + result->error);
  }
  const QString warn = preview_->limit_warning();
  if (!warn.isEmpty()) screen_.log(LogLevel::Warning, warn.simplified().toStdString());
}

// ------------------------------------------------------------ run from line

void MainWindow::request_run_from_line(int line) {
  if (run_from_line_box_) run_from_line_box_->close();
  pending_run_from_line_ = 0;
  screen_.send_in_mode(ipc::TaskMode::Auto, {commands::run_preview(line)}, "run from line " + std::to_string(line) + " (preview)",
                       [this, line](const ipc::CommandResult& r) {
                         if (r.state == ipc::CommandState::Done) pending_run_from_line_ = line;
                       });
}

void MainWindow::check_run_from_line() {
  const auto& st = screen_.status;
  if (pending_run_from_line_ == 0 || st.task.run_from_line_pending != pending_run_from_line_) return;
  const int line = pending_run_from_line_;
  pending_run_from_line_ = 0;
  const Pose from = st.motion.position, to = st.task.run_from_line_start;
  preview_->set_approach(from, to);
  const int dec = config_.dro_decimals(config_.machine_inch);
  const QString text =
      QString("Run the program from line %1?\n\nThe machine first moves (machine coordinates):\n"
              "  up to Z %2\n  across to X %3 Y %4\n  down to Z %5 at a reduced feed\n"
              "then restores tool, offsets, spindle and coolant as the program has them at that line.\n"
              "The approach is drawn in orange on the preview.")
          .arg(line)
          .arg(screen_.number(std::max(from[2], to[2]), dec), screen_.number(to[0], dec), screen_.number(to[1], dec),
               screen_.number(to[2], dec));
  auto* box = new QMessageBox(QMessageBox::Question, "Run from line", text, QMessageBox::NoButton, this);
  box->setObjectName("runFromLineDialog");
  box->setAttribute(Qt::WA_DeleteOnClose);
  QPushButton* run = box->addButton("Run from here", QMessageBox::AcceptRole);
  run->setObjectName("runFromLineConfirm");
  box->addButton(QMessageBox::Cancel);
  connect(box, &QMessageBox::finished, this, [this, box, run, line](int) {
    preview_->clear_approach();
    if (box->clickedButton() != run) {
      screen_.log(LogLevel::Operator, "run from line " + std::to_string(line) + " cancelled");
      return;
    }
    screen_.send_in_mode(ipc::TaskMode::Auto, {commands::run(line)}, "run from line " + std::to_string(line));
  });
  run_from_line_box_ = box;
  box->open();
}

// ------------------------------------------------------------ HAL pins and dialogs

void MainWindow::hal_setup() {
  if (!hal_) return;
  hal_pending_ = 0;
  if (!dialogs_.config().empty()) {
    for (const auto& line : dialogs_.setup_commands()) {
      hal_->request(QString::fromStdString(line), kTagSetup);
      ++hal_pending_;
    }
  }
  // POSTGUI: after the screen's pins exist (the requests run in order).
  // The screen reads the files itself and sends their lines: the
  // controller never reads a file for a client (docs/security.md).
  for (const auto& f : config_.postgui_halfiles) {
    std::string text;
    try {
      text = read_file(f);
    } catch (const std::exception& e) {
      screen_.log(LogLevel::Error, std::string("POSTGUI: ") + e.what(), "hal");
      continue;
    }
    for (const NumberedLine& l : continued_lines(text)) {
      if (trim(l.text).empty() || trim(l.text).front() == '#') continue;
      hal_->request(QString::fromStdString(l.text), kTagPostgui);
      ++hal_pending_;
    }
  }
  for (const auto& c : config_.postgui_halcmds) {
    hal_->request(QString::fromStdString(c), kTagPostgui);
    ++hal_pending_;
  }
  if (!dialogs_.config().empty()) hal_->set_poll(QString::fromStdString(dialogs_.poll_pattern()), config_.cycle_time_ms);
}

void MainWindow::hal_replied(int tag, const QString& line, bool ok, const QString& text) {
  if (tag >= ScopePage::kTagFirst && tag <= ScopePage::kTagLast) return;  // the Scope page's own
  if (tag == kTagSetup || tag == kTagPostgui) hal_pending_ = std::max(0, hal_pending_ - 1);
  if (ok) {
    if (tag == kTagPostgui) {
      screen_.log(LogLevel::Info, "POSTGUI: " + line.toStdString() + (text.trimmed().isEmpty() ? "" : "\n" + text.trimmed().toStdString()), "hal");
    }
    return;
  }
  // A screen restarted on a running controller finds its pins already there.
  if (tag == kTagSetup && text.contains("already")) return;
  screen_.log(tag == kTagSetr ? LogLevel::Warning : LogLevel::Error,
              (tag == kTagPostgui ? "POSTGUI " : "halcmd ") + line.toStdString() + ": " + text.toStdString(), "hal");
}

void MainWindow::apply_dialog_actions(const std::vector<UserDialogLogic::Action>& actions) {
  using Kind = UserDialogLogic::Action::Kind;
  for (const auto& a : actions) {
    switch (a.kind) {
      case Kind::Set:
        if (hal_) hal_->request(QString::fromStdString("setr " + a.pin + " " + a.value), kTagSetr);
        break;
      case Kind::Log: screen_.log(LogLevel::Warning, a.value, "hal"); break;
      case Kind::Status: {
        const UserMessage* m = a.message;
        std::string text = m->title.empty() ? m->text : m->title + (m->text.empty() ? "" : ": " + m->text);
        screen_.log(LogLevel::Display, text, "hal:" + m->pin);
        break;
      }
      case Kind::Close: {
        auto it = user_boxes_.find(a.message);
        if (it != user_boxes_.end()) {
          QPointer<QMessageBox> box = it->second;
          user_boxes_.erase(it);
          if (box) {
            box->disconnect(this);
            box->close();
          }
        }
        break;
      }
      case Kind::Show: {
        const UserMessage* m = a.message;
        if (user_boxes_.count(m)) break;
        QMessageBox::Icon icon = QMessageBox::Information;
        const QString ic = QString::fromStdString(m->icon).toUpper();
        if (ic == "WARNING") icon = QMessageBox::Warning;
        else if (ic == "CRITICAL") icon = QMessageBox::Critical;
        else if (ic == "QUESTION" || m->yesno) icon = QMessageBox::Question;
        auto* box = new QMessageBox(icon, QString::fromStdString(m->title.empty() ? config_.title : m->title),
                                    QString::fromStdString(m->title.empty() ? m->text : "<b>" + m->title + "</b><br>" + m->text),
                                    QMessageBox::NoButton, this);
        box->setObjectName(QString::fromStdString("userDialog_" + m->pin + (m->number ? "_" + std::to_string(m->number) : "")));
        box->setAttribute(Qt::WA_DeleteOnClose);
        box->setWindowModality(Qt::NonModal);
        if (!m->details.empty()) box->setInformativeText(QString::fromStdString(m->details));
        if (m->yesno) box->setStandardButtons(QMessageBox::Yes | QMessageBox::No);
        else if (m->ok) box->setStandardButtons(QMessageBox::Ok);
        connect(box, &QMessageBox::finished, this, [this, m, box](int) {
          user_boxes_.erase(m);
          const auto b = box->standardButton(box->clickedButton());
          apply_dialog_actions(dialogs_.answer(m, b == QMessageBox::Yes || b == QMessageBox::Ok));
          screen_.log(LogLevel::Operator, "dialog " + m->pin + ": " + (m->yesno ? (b == QMessageBox::Yes ? "yes" : "no") : "ok"));
        });
        user_boxes_[m] = box;
        box->show();
        break;
      }
    }
  }
}

// ------------------------------------------------------------ keys and focus

bool MainWindow::handle_key(QKeyEvent* e, bool press) {
  if (e->isAutoRepeat()) {
    const auto [axis, dir] = jog_key(e->key(), config_.lathe, config_.back_tool_lathe);
    return axis >= 0 && !ui::is_text_input(QApplication::focusWidget());  // swallow repeats of held jog keys
  }
  if (press && e->key() == Qt::Key_Escape) {
    // Esc also gives the keys back to jogging.
    if (QWidget* f = QApplication::focusWidget(); f && ui::is_text_input(f)) f->clearFocus();
    jog_.stop_all();
    screen_.send(commands::abort(), "stop (Esc)");
    return true;
  }
  if (press && e->key() == Qt::Key_F1) {
    screen_.estop("E-stop (F1)");
    return true;
  }
  if (ui::is_text_input(QApplication::focusWidget())) return false;  // the text field gets the key
  const auto [axis, dir] = jog_key(e->key(), config_.lathe, config_.back_tool_lathe);
  if (axis < 0 || !config_.axis(axis)) return false;
  if (press) {
    if (!jog_.press(axis, dir, JogController::Source::Key) && !jog_.why_not().empty() && jog_.keyboard_enabled()) {
      screen_.log(LogLevel::Warning, "jog: " + jog_.why_not());
    }
  } else {
    jog_.release(axis, JogController::Source::Key);
  }
  return true;
}

bool MainWindow::eventFilter(QObject* watched, QEvent* e) {
  if (e->type() == QEvent::KeyPress || e->type() == QEvent::KeyRelease) {
    // Keys count only while this window (not a dialog) is the active one.
    if (QApplication::activeWindow() == this && watched->isWidgetType() &&
        static_cast<QWidget*>(watched)->window() == this) {
      return handle_key(static_cast<QKeyEvent*>(e), e->type() == QEvent::KeyPress);
    }
  }
  return QMainWindow::eventFilter(watched, e);
}

void MainWindow::changeEvent(QEvent* e) {
  if (e->type() == QEvent::ActivationChange && !isActiveWindow()) jog_.focus_lost();
  QMainWindow::changeEvent(e);
}

void MainWindow::closeEvent(QCloseEvent* e) {
  jog_.stop_all();
  tracker_.poll(monotonic_ns());
  QMainWindow::closeEvent(e);
}

}  // namespace cnc::hmi
