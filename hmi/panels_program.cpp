// Program controls and the MDI page.
#include <QEvent>
#include <QFileInfo>
#include <QGridLayout>
#include <QHBoxLayout>
#include <QKeyEvent>
#include <QLabel>
#include <QLineEdit>
#include <QListWidget>
#include <QPushButton>
#include <QScroller>
#include <QSpinBox>
#include <QVBoxLayout>

#include <stdexcept>

#include "hmi/mdi_history.hpp"
#include "hmi/panels.hpp"
#include "hmi/readouts.hpp"

namespace cnc::hmi {

// ------------------------------------------------------------ ProgramBar

ProgramBar::ProgramBar(Screen& s, QWidget* parent) : QWidget(parent), s_(s) {
  setObjectName("programBar");
  auto* v = new QVBoxLayout(this);
  v->setContentsMargins(4, 2, 4, 2);
  v->setSpacing(2);
  auto* row = new QHBoxLayout();
  open_ = ui::button("Open…", "openButton", this);
  reload_ = ui::button("Reload", "reloadButton", this);
  run_ = ui::button("▶ Cycle start", "runButton", this);
  pause_ = ui::button("❚❚ Feed hold", "pauseButton", this);
  resume_ = ui::button("▶ Resume", "resumeButton", this);
  step_ = ui::button("Step", "stepButton", this);
  abort_ = ui::button("■ Stop", "abortButton", this);
  optional_stop_ = ui::button("M1 stop", "optionalStop", this, true);
  block_delete_ = ui::button("/ skip", "blockDelete", this, true);
  run_->setStyleSheet("QPushButton:enabled{background:#2a8a2a;color:white;font-weight:bold;}");
  abort_->setStyleSheet("QPushButton{background:#a02020;color:white;font-weight:bold;}");
  optional_stop_->setToolTip("Optional stop: M1 stops the program when on");
  block_delete_->setToolTip("Block delete: lines starting with / are skipped when on (from the next start)");
  for (auto* b : {open_, reload_, run_, pause_, resume_, step_, abort_, optional_stop_, block_delete_}) row->addWidget(b);
  v->addLayout(row);
  line_row_ = new QWidget(this);
  line_row_->setObjectName("runFromLineRow");
  auto* row2 = new QHBoxLayout(line_row_);
  row2->setContentsMargins(0, 0, 0, 0);
  row2->addWidget(new QLabel("From line", line_row_));
  line_ = new QSpinBox(line_row_);
  line_->setObjectName("runFromLineNumber");
  line_->setRange(1, 100000000);
  line_->setMinimumHeight(ui::kTouch - 8);
  line_->setMinimumWidth(90);
  line_->setFocusPolicy(Qt::ClickFocus);
  run_from_ = ui::button("Run from line…", "runFromLine", line_row_);
  row2->addWidget(line_);
  row2->addWidget(run_from_);
  progress_ = new QLabel(line_row_);
  progress_->setObjectName("programProgress");
  progress_->setWordWrap(true);  // line, %, times and errors: long; it wraps rather than widen the window
  row2->addWidget(progress_, 1);

  connect(open_, &QPushButton::clicked, this, &ProgramBar::openRequested);
  connect(reload_, &QPushButton::clicked, this, &ProgramBar::reloadRequested);
  connect(run_, &QPushButton::clicked, this, [this]() {
    s_.send_in_mode(ipc::TaskMode::Auto, {commands::run(0)}, "cycle start");
  });
  connect(pause_, &QPushButton::clicked, this, [this]() { s_.send(commands::pause(), "feed hold"); });
  connect(resume_, &QPushButton::clicked, this, [this]() { s_.send(commands::resume(), "resume"); });
  connect(step_, &QPushButton::clicked, this, [this]() {
    if (s_.status.task.paused) s_.send(commands::step(), "step");
    else s_.send_in_mode(ipc::TaskMode::Auto, {commands::step()}, "step");
  });
  connect(abort_, &QPushButton::clicked, this, [this]() {
    s_.jog.stop_all();
    s_.send(commands::abort(), "stop");
  });
  connect(optional_stop_, &QPushButton::clicked, this, [this]() {
    const bool want = !s_.status.task.optional_stop;
    refresh();
    s_.send(commands::optional_stop(want), want ? "optional stop on" : "optional stop off");
  });
  connect(block_delete_, &QPushButton::clicked, this, [this]() {
    const bool want = !s_.status.task.block_delete;
    refresh();
    s_.send(commands::block_delete(want), want ? "block delete on" : "block delete off");
  });
  connect(run_from_, &QPushButton::clicked, this, [this]() { emit runFromLineRequested(line_->value()); });
  refresh();
}

void ProgramBar::refresh() {
  const auto& st = s_.status;
  const bool c = s_.connected;
  const bool idle = s_.is_idle();
  const bool on = s_.is_on();
  const bool file = c && !st.task.file.empty();
  const bool running = c && !idle;
  open_->setEnabled(c && idle);
  reload_->setEnabled(file && idle);
  run_->setEnabled(on && idle && file);
  pause_->setEnabled(on && running && !st.task.paused);
  resume_->setEnabled(on && st.task.paused);
  step_->setEnabled(on && file && (idle || st.task.paused));
  abort_->setEnabled(c);
  run_from_->setEnabled(on && idle && file);
  optional_stop_->setChecked(c && st.task.optional_stop);
  block_delete_->setChecked(c && st.task.block_delete);
  if (!c) {
    ui::set_text(progress_, "");
    return;
  }
  if (!file) {
    ui::set_text(progress_, "no program open");
    return;
  }
  const QString name = QFileInfo(ui::qs(st.task.file.view())).fileName();
  // the planner's estimate, when it is for the program the controller has open
  const bool estimate_for_it =
      !s_.estimate_file.empty() && QFileInfo(ui::qs(st.task.file.view())).canonicalFilePath().toStdString() == s_.estimate_file;
  QString text = name + " · " + ui::qs(progress_readout(st, estimate_for_it ? s_.estimate_s : -1));
  ui::set_text(progress_, text);
}

// ------------------------------------------------------------ MdiPage

namespace {
// Up/Down in the MDI line walk through the history.
class HistoryKeys : public QObject {
 public:
  HistoryKeys(QLineEdit* input, MdiHistory& history) : QObject(input), input_(input), history_(history) {}
  bool eventFilter(QObject*, QEvent* e) override {
    if (e->type() != QEvent::KeyPress) return false;
    const int key = static_cast<QKeyEvent*>(e)->key();
    if (key != Qt::Key_Up && key != Qt::Key_Down) return false;
    const auto& list = history_.entries();
    if (list.empty()) return true;
    const int n = static_cast<int>(list.size());
    pos_ = key == Qt::Key_Up ? std::max(0, (pos_ < 0 ? n : pos_) - 1) : std::min(n, pos_ + 1);
    input_->setText(pos_ >= n ? QString() : QString::fromStdString(list[static_cast<std::size_t>(pos_)]));
    if (pos_ >= n) pos_ = -1;
    return true;
  }

 private:
  QLineEdit* input_;
  MdiHistory& history_;
  int pos_ = -1;
};
}  // namespace

MdiPage::MdiPage(Screen& s, MdiHistory& history, QWidget* parent) : QWidget(parent), s_(s), history_(history) {
  setObjectName("mdiPage");
  auto* v = new QVBoxLayout(this);
  auto* row = new QHBoxLayout();
  input_ = new QLineEdit(this);
  input_->setObjectName("mdiInput");
  input_->setPlaceholderText("G-code, e.g. G0 X10 Y10");
  input_->setMinimumHeight(ui::kTouch);
  input_->setMaxLength(254);
  input_->setFocusPolicy(Qt::ClickFocus);
  input_->installEventFilter(new HistoryKeys(input_, history_));
  send_ = ui::button("Send", "mdiSend", this);
  row->addWidget(input_, 1);
  row->addWidget(send_);
  v->addLayout(row);
  active_ = new QLabel(this);
  active_->setObjectName("mdiActive");
  v->addWidget(active_);
  if (!s_.config.macros.empty()) {
    auto* grid = new QGridLayout();
    int i = 0;
    for (const auto& m : s_.config.macros) {
      auto* b = ui::button(QString::fromStdString(m.label), ("macro_" + std::to_string(m.index)).c_str(), this);
      b->setToolTip(QString::fromStdString(m.commands));
      b->setMinimumHeight(ui::kTouch + 10);
      const int index = m.index;
      connect(b, &QPushButton::clicked, this, [this, index]() { run_macro(index); });
      grid->addWidget(b, i / 4, i % 4);
      macros_.push_back(b);
      ++i;
    }
    v->addLayout(grid);
  }
  auto* hrow = new QHBoxLayout();
  hrow->addWidget(new QLabel("History (tap: edit, double tap: run)", this), 1);
  auto* clear = ui::button("Clear history", "mdiClearHistory", this);
  hrow->addWidget(clear);
  v->addLayout(hrow);
  list_ = new QListWidget(this);
  list_->setObjectName("mdiHistory");
  list_->setFocusPolicy(Qt::NoFocus);
  QScroller::grabGesture(list_->viewport(), QScroller::TouchGesture);
  v->addWidget(list_, 1);
  connect(send_, &QPushButton::clicked, this, [this]() { submit(input_->text()); });
  connect(input_, &QLineEdit::returnPressed, this, [this]() { submit(input_->text()); });
  connect(list_, &QListWidget::itemClicked, this, [this](QListWidgetItem* it) { input_->setText(it->text()); });
  connect(list_, &QListWidget::itemDoubleClicked, this, [this](QListWidgetItem* it) { submit(it->text()); });
  connect(clear, &QPushButton::clicked, this, [this]() {
    if (!history_.clear()) s_.log(LogLevel::Warning, "MDI history: " + history_.error());
    reload_history();
  });
  reload_history();
}

void MdiPage::reload_history() {
  list_->clear();
  for (const auto& e : history_.entries()) list_->addItem(QString::fromStdString(e));
  list_->scrollToBottom();
}

void MdiPage::submit(const QString& text) {
  const std::string line = text.trimmed().toStdString();
  if (line.empty()) return;
  ipc::Command cmd;
  try {
    cmd = commands::mdi(line);
  } catch (const std::invalid_argument& e) {
    s_.log(LogLevel::Error, std::string("MDI not sent: ") + e.what());  // the line stays in the field
    return;
  }
  input_->clear();
  s_.send_in_mode(ipc::TaskMode::Mdi, {cmd}, "MDI " + line, [this, line](const ipc::CommandResult& r) {
    // Only lines the controller executed go into the history.
    if (r.state != ipc::CommandState::Done) return;
    if (!history_.add(line)) s_.log(LogLevel::Warning, "MDI history not saved: " + history_.error());
    reload_history();
  });
}

void MdiPage::run_macro(int index) {
  std::string label = "macro " + std::to_string(index);
  for (const auto& m : s_.config.macros) {
    if (m.index == index) label += " (" + m.commands + ")";
  }
  s_.send_in_mode(ipc::TaskMode::Mdi, {commands::macro(index)}, label);
}

void MdiPage::refresh() {
  const auto& st = s_.status;
  const bool ok = s_.is_on() && (s_.is_idle() || st.task.mode == ipc::TaskMode::Mdi);
  send_->setEnabled(ok);
  for (auto* b : macros_) b->setEnabled(ok && s_.is_idle());
  QString a;
  if (s_.connected) a = ui::qs(mdi_running_readout(st));
  if (s_.connected && st.task.queued_mdi > 0) a += QString("  (%1 queued)").arg(st.task.queued_mdi);
  ui::set_text(active_, a);
}

}  // namespace cnc::hmi
