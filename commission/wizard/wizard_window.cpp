#include "commission/wizard/wizard_window.hpp"

#include <signal.h>

#include <QCoreApplication>
#include <QFileInfo>
#include <QFocusEvent>
#include <QHBoxLayout>
#include <QLabel>
#include <QListWidget>
#include <QPlainTextEdit>
#include <QProgressBar>
#include <QStackedWidget>
#include <QTimer>
#include <QVBoxLayout>

#include "core/ipc/status.hpp"
#include "hmi/link.hpp"

namespace cnc::commission::wizard {

// ------------------------------------------------------------ ChildRun

ChildRun::ChildRun(QObject* parent) : QObject(parent) {
  connect(&proc_, &QProcess::started, this, [this] { emit started(); });
  connect(&proc_, &QProcess::readyReadStandardOutput, this, [this] {
    const QByteArray b = proc_.readAllStandardOutput();
    for (const Progress& p : out_.add_stdout(std::string_view(b.constData(), static_cast<std::size_t>(b.size()))))
      emit progress(p.index, p.count, QString::fromStdString(p.text));
    for (; shown_lines_ < out_.lines().size(); ++shown_lines_) emit output(QString::fromStdString(out_.lines()[shown_lines_]));
  });
  connect(&proc_, &QProcess::readyReadStandardError, this, [this] {
    const QByteArray b = proc_.readAllStandardError();
    out_.add_stderr(std::string_view(b.constData(), static_cast<std::size_t>(b.size())));
  });
  connect(&proc_, &QProcess::finished, this, [this](int code, QProcess::ExitStatus st) {
    const QByteArray o = proc_.readAllStandardOutput(), e = proc_.readAllStandardError();
    out_.add_stdout(std::string_view(o.constData(), static_cast<std::size_t>(o.size())));
    out_.add_stderr(std::string_view(e.constData(), static_cast<std::size_t>(e.size())));
    const StepResult r = out_.finish(st == QProcess::NormalExit, code, abort_requested_);
    for (; shown_lines_ < r.lines.size(); ++shown_lines_) emit output(QString::fromStdString(r.lines[shown_lines_]));
    emit finished(r);
  });
  connect(&proc_, &QProcess::errorOccurred, this, [this](QProcess::ProcessError e) {
    if (e != QProcess::FailedToStart) return;
    StepResult r;
    r.outcome = StepResult::Outcome::Crashed;
    r.error = (proc_.program() + " did not start: " + proc_.errorString()).toStdString();
    emit finished(r);
  });
}

ChildRun::~ChildRun() {
  if (running()) {  // the window closes during a motion: stop it as a release would
    ::kill(static_cast<pid_t>(proc_.processId()), SIGINT);
    if (!proc_.waitForFinished(15000)) proc_.kill();
    proc_.waitForFinished(1000);
  }
}

bool ChildRun::start(const QString& program, const Argv& args) {
  if (running()) return false;
  out_ = OutputCollector{};
  shown_lines_ = 0;
  abort_requested_ = false;
  QStringList a;
  for (const auto& s : args) a << QString::fromStdString(s);
  command_ = QFileInfo(program).fileName() + " " + a.join(' ');
  proc_.start(program, a);
  return true;
}

void ChildRun::interrupt() {
  if (!running() || proc_.processId() <= 0) return;
  abort_requested_ = true;
  ::kill(static_cast<pid_t>(proc_.processId()), SIGINT);
}

// ------------------------------------------------------------ HoldToRunButton

HoldToRunButton::HoldToRunButton(const QString& text, QWidget* parent) : QPushButton(text, parent) {
  setAutoRepeat(false);
  connect(this, &QPushButton::pressed, this, &HoldToRunButton::on_press);
  connect(this, &QPushButton::released, this, &HoldToRunButton::on_release);
}

void HoldToRunButton::on_press() {
  if (hold_.press() == HoldToRun::Action::Start) emit startRequested();
}

void HoldToRunButton::on_release() {
  if (hold_.release() == HoldToRun::Action::Interrupt) emit interruptRequested();
}

void HoldToRunButton::focusOutEvent(QFocusEvent* e) {
  on_release();  // a press that loses the window is a release
  QPushButton::focusOutEvent(e);
}

// ------------------------------------------------------------ StepPage

StepPage::StepPage(WizardWindow& w, int step, const QString& intro) : w_(w), step_(step) {
  setObjectName(QString("page%1").arg(step + 1));
  auto* v = new QVBoxLayout(this);
  auto* title = new QLabel(QString("<h2>%1. %2</h2>").arg(step + 1).arg(step_title(step)));
  v->addWidget(title);
  auto* text = new QLabel(intro);
  text->setWordWrap(true);
  v->addWidget(text);
  inputs_ = new QWidget;
  v->addWidget(inputs_, 3);
  progress_ = new QProgressBar;
  progress_->setObjectName("stepProgress");
  progress_->setRange(0, 1);
  progress_->setValue(0);
  progress_->setFormat("%p%");
  auto* prow = new QHBoxLayout;
  prow->addWidget(progress_, 1);
  // Any running step stops as a released hold-to-run button stops it.
  stop_ = new QPushButton("Stop");
  stop_->setObjectName("stopButton");
  stop_->setEnabled(false);
  prow->addWidget(stop_);
  v->addLayout(prow);
  result_ = new QLabel;
  result_->setObjectName("stepResult");
  result_->setWordWrap(true);
  result_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  v->addWidget(result_);
  output_ = new QPlainTextEdit;
  output_->setObjectName("stepOutput");
  output_->setReadOnly(true);
  output_->setMaximumBlockCount(2000);
  output_->setMinimumHeight(120);
  v->addWidget(output_, 1);
  child_ = new ChildRun(this);
  connect(stop_, &QPushButton::clicked, child_, &ChildRun::interrupt);
  connect(child_, &ChildRun::started, this, [this] { stop_->setEnabled(true); });
  connect(child_, &ChildRun::progress, this, [this](int i, int n, const QString& t) {
    progress_->setRange(0, n);
    progress_->setValue(i);
    progress_->setFormat(QString("%1/%2 %3").arg(i).arg(n).arg(t));
  });
  connect(child_, &ChildRun::output, this, [this](const QString& l) { output_->appendPlainText(l); });
  connect(child_, &ChildRun::finished, this, [this](const StepResult& r) {
    stop_->setEnabled(false);
    if (!r.error.empty()) output_->appendPlainText(QString::fromStdString(r.error));
    if (progress_->maximum() == 0) progress_->setRange(0, 1);
    if (r.ok()) progress_->setValue(progress_->maximum());
    result_->setStyleSheet(r.ok() ? "color: #1a7f1a; font-weight: bold" : "color: #c00000; font-weight: bold");
    result_->setText(QString::fromStdString(r.summary()));
    w_.reload_state();
    if (then_) then_(r);
  });
}

void StepPage::show_error(const QString& text) {
  result_->setStyleSheet("color: #c00000; font-weight: bold");
  result_->setText(text);
}

bool StepPage::run(const std::function<Argv()>& build, std::function<void(const StepResult&)> then) {
  if (child_->running()) {
    show_error("a step is still running");
    return false;
  }
  Argv args;
  try {
    args = build();
  } catch (const std::exception& e) {
    show_error(QString("input: ") + e.what());
    return false;
  }
  then_ = std::move(then);
  output_->clear();
  progress_->setRange(0, 0);  // busy until the first progress line
  result_->setStyleSheet("");
  child_->start(w_.options().program, args);
  result_->setText("running: " + child_->command_line());
  output_->appendPlainText("$ " + child_->command_line());
  return true;
}

// ------------------------------------------------------------ WizardWindow

WizardWindow::WizardWindow(WizardOptions options, std::unique_ptr<hmi::MachineLink> link, QWidget* parent)
    : QMainWindow(parent), options_(std::move(options)), builder_(options_.state_file.toStdString()), link_(std::move(link)) {
  setWindowTitle("Commissioning - " + options_.state_file);
  if (options_.program.isEmpty()) options_.program = QCoreApplication::applicationDirPath() + "/cnc-commission";
  if (options_.config_dir.isEmpty())
    options_.config_dir = QFileInfo(options_.state_file).absolutePath() + "/commission-config";
  auto* central = new QWidget;
  auto* outer = new QVBoxLayout(central);
  auto* top = new QHBoxLayout;
  outer->addLayout(top, 1);
  auto* left = new QVBoxLayout;
  steps_ = new QListWidget;
  steps_->setObjectName("stepList");
  steps_->setMaximumWidth(220);
  left->addWidget(steps_, 1);
  overall_ = new QProgressBar;
  overall_->setObjectName("stepsDone");
  overall_->setRange(0, kSteps);
  overall_->setFormat("%v of 9 steps done");
  left->addWidget(overall_);
  top->addLayout(left);
  auto* right = new QVBoxLayout;
  state_error_ = new QLabel;
  state_error_->setObjectName("stateError");
  state_error_->setStyleSheet("color: #c00000");
  state_error_->setWordWrap(true);
  state_error_->hide();
  right->addWidget(state_error_);
  stack_ = new QStackedWidget;
  right->addWidget(stack_, 1);
  auto* nav = new QHBoxLayout;
  back_ = new QPushButton("< Back");
  back_->setObjectName("backButton");
  next_ = new QPushButton("Next >");
  next_->setObjectName("nextButton");
  nav->addStretch(1);
  nav->addWidget(back_);
  nav->addWidget(next_);
  right->addLayout(nav);
  top->addLayout(right, 1);
  // The status strip.
  auto* strip = new QFrame;
  strip->setObjectName("statusStrip");
  strip->setFrameShape(QFrame::StyledPanel);
  auto* sl = new QHBoxLayout(strip);
  estop_ = new QLabel;
  estop_->setObjectName("estopStatus");
  drives_ = new QLabel;
  drives_->setObjectName("drivesStatus");
  positions_ = new QLabel;
  positions_->setObjectName("positionsStatus");
  sl->addWidget(estop_);
  sl->addWidget(drives_, 1);
  sl->addWidget(positions_, 1);
  outer->addWidget(strip);
  setCentralWidget(central);

  for (int i = 0; i < kSteps; ++i) {
    steps_->addItem(QString("%1. %2").arg(i + 1).arg(step_title(i)));
    pages_.push_back(make_page(*this, i));
    stack_->addWidget(pages_.back());
  }
  connect(steps_, &QListWidget::currentRowChanged, this, [this](int row) {
    if (row >= 0) show_step(row);
  });
  connect(back_, &QPushButton::clicked, this, [this] { show_step(current_step() - 1); });
  connect(next_, &QPushButton::clicked, this, [this] { show_step(current_step() + 1); });
  timer_ = new QTimer(this);
  connect(timer_, &QTimer::timeout, this, &WizardWindow::update_status);
  timer_->start(options_.status_period_ms);
  reload_state();
  update_status();
  // Resume where the work stopped: the first step not done.
  int first = 0;
  while (first < kSteps - 1 && done_[static_cast<std::size_t>(first)]) ++first;
  show_step(first);
}

WizardWindow::~WizardWindow() = default;

int WizardWindow::current_step() const { return stack_->currentIndex(); }

StepPage* WizardWindow::page(int step) const { return pages_.at(static_cast<std::size_t>(step)); }

void WizardWindow::show_step(int step) {
  if (step < 0 || step >= kSteps) return;
  stack_->setCurrentIndex(step);
  if (steps_->currentRow() != step) steps_->setCurrentRow(step);
  back_->setEnabled(step > 0);
  next_->setEnabled(step < kSteps - 1);
}

void WizardWindow::reload_state() {
  try {
    state_ = load_state(options_.state_file.toStdString());
    done_ = steps_done(std::filesystem::path(options_.state_file.toStdString()));
    state_error_->hide();
  } catch (const std::exception& e) {
    state_error_->setText(QString("state file: ") + e.what());
    state_error_->show();
  }
  int n = 0;
  for (int i = 0; i < kSteps; ++i) {
    const bool d = done_[static_cast<std::size_t>(i)];
    n += d ? 1 : 0;
    steps_->item(i)->setText(QString("%1. %2%3").arg(i + 1).arg(step_title(i)).arg(d ? QString::fromUtf8("  \u2713") : ""));
    steps_->item(i)->setForeground(d ? QColor(0x1a, 0x7f, 0x1a) : palette().color(QPalette::Text));
  }
  overall_->setValue(n);
  for (auto* p : pages_) p->refresh(state_);
}

void WizardWindow::update_status() {
  ipc::Status s;
  std::string why;
  if (!link_ || !link_->read_status(s, why)) {
    estop_->setText("<b>no controller</b>");
    estop_->setStyleSheet("color: #808080");
    drives_->setText(QString::fromStdString(why.empty() ? "no controller runs on this instance" : why));
    positions_->clear();
    return;
  }
  const StatusStrip st = status_strip(s);
  estop_->setText("<b>" + QString::fromStdString(st.estop).toHtmlEscaped() + "</b>");
  estop_->setStyleSheet(st.estop_ok ? "color: #1a7f1a" : "color: #c00000");
  QStringList d, p;
  for (const auto& x : st.drives) d << QString::fromStdString(x);
  for (const auto& x : st.joints) p << QString::fromStdString(x);
  drives_->setText(d.isEmpty() ? "no drives" : d.join("  |  "));
  positions_->setText(p.join("   "));
}

}  // namespace cnc::commission::wizard
