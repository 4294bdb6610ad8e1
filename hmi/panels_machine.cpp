// Status strip, DRO, manual panel (homing, jogging, spindle, coolant) and
// overrides.
#include <QAbstractSpinBox>
#include <QApplication>
#include <QButtonGroup>
#include <QComboBox>
#include <QGridLayout>
#include <QHBoxLayout>
#include <QInputDialog>
#include <QLabel>
#include <QLineEdit>
#include <QPlainTextEdit>
#include <QProgressBar>
#include <QPushButton>
#include <QSlider>
#include <QTextEdit>
#include <QVBoxLayout>
#include <algorithm>
#include <cmath>

#include "hmi/panels.hpp"
#include "hmi/readouts.hpp"
#include "hmi/positions.hpp"

namespace cnc::hmi {

// ------------------------------------------------------------ Screen, ui

void Screen::log(LogLevel level, const std::string& text, const std::string& source) {
  alarms.post_local(level, source, text, now_ns ? now_ns() : 0);
}

bool Screen::send(const ipc::Command& cmd, const std::string& what, CommandTracker::Done done) {
  return tracker.send(cmd, what, std::move(done));
}

bool Screen::estop(const std::string& what) {
  jog.stop_all();
  return tracker.estop(what);
}

bool Screen::send_in_mode(ipc::TaskMode mode, std::vector<ipc::Command> cmds, const std::string& what,
                          CommandTracker::Done done) {
  if (!connected || status.task.mode != mode) {
    jog.stop_all();
    cmds.insert(cmds.begin(), commands::set_mode(mode));
  }
  return tracker.send_sequence(std::move(cmds), what, std::move(done));
}

bool Screen::all_homed() const {
  if (!connected || status.motion.joints <= 0) return false;
  for (int j = 0; j < std::min<int>(status.motion.joints, kMaxJoints); ++j) {
    if (!status.joints[j].homed) return false;
  }
  return true;
}

std::string Screen::tool_text(int tool) const {
  if (tool <= 0) return "no tool";
  std::string t = "T" + std::to_string(tool);
  if (const auto idx = tools.find_tool_anywhere(tool)) {
    const auto& data = tools.at(*idx);
    if (!data.comment.empty()) t += " " + data.comment;
  }
  return t;
}

namespace ui {

void set_text(QLabel* label, const QString& text) {
  if (label->text() != text) label->setText(text);
}
void set_text(QPushButton* button, const QString& text) {
  if (button->text() != text) button->setText(text);
}
void set_style(QWidget* w, const QString& sheet) {
  if (w->styleSheet() != sheet) w->setStyleSheet(sheet);
}

QPushButton* button(const QString& text, const char* object_name, QWidget* parent, bool checkable) {
  auto* b = new QPushButton(text, parent);
  b->setObjectName(object_name);
  b->setMinimumHeight(kTouch);
  b->setCheckable(checkable);
  b->setFocusPolicy(Qt::NoFocus);  // buttons never steal the keyboard from jogging
  return b;
}

bool is_text_input(const QWidget* w) {
  if (!w) return false;
  if (qobject_cast<const QLineEdit*>(w) || qobject_cast<const QAbstractSpinBox*>(w)) return true;
  if (const auto* p = qobject_cast<const QPlainTextEdit*>(w)) return !p->isReadOnly();
  if (const auto* t = qobject_cast<const QTextEdit*>(w)) return !t->isReadOnly();
  if (const auto* c = qobject_cast<const QComboBox*>(w)) return c->isEditable();
  return false;
}

}  // namespace ui

// ------------------------------------------------------------ StatusStrip

namespace {
const char* kModeNames[3] = {"MANUAL", "MDI", "AUTO"};
const ipc::TaskMode kModes[3] = {ipc::TaskMode::Manual, ipc::TaskMode::Mdi, ipc::TaskMode::Auto};
}  // namespace

StatusStrip::StatusStrip(Screen& s, QWidget* parent) : QWidget(parent), s_(s) {
  setObjectName("statusStrip");
  auto* row = new QHBoxLayout(this);
  row->setContentsMargins(4, 4, 4, 4);
  estop_ = ui::button("E-STOP", "estopButton", this);
  estop_->setMinimumSize(110, 54);
  machine_ = ui::button("MACHINE\nOFF", "machineButton", this, true);
  machine_->setMinimumSize(100, 54);
  row->addWidget(estop_);
  row->addWidget(machine_);
  row->addSpacing(8);
  for (int i = 0; i < 3; ++i) {
    const char* names[3] = {"modeManual", "modeMdi", "modeAuto"};
    modes_[static_cast<std::size_t>(i)] = ui::button(kModeNames[i], names[i], this, true);
    modes_[static_cast<std::size_t>(i)]->setMinimumSize(84, 54);
    row->addWidget(modes_[static_cast<std::size_t>(i)]);
    connect(modes_[static_cast<std::size_t>(i)], &QPushButton::clicked, this, [this, i]() {
      refresh();  // the check mark follows the controller, not the click
      // MANUAL means jogging: a text field must not keep the keys.
      if (QWidget* f = QApplication::focusWidget(); kModes[i] == ipc::TaskMode::Manual && f && ui::is_text_input(f)) f->clearFocus();
      s_.send_in_mode(kModes[i], {}, std::string("mode ") + kModeNames[i]);
    });
  }
  row->addSpacing(8);
  auto* middle = new QVBoxLayout();
  state_ = new QLabel(this);
  state_->setObjectName("stateLabel");
  message_ = new QLabel(this);
  message_->setObjectName("messageLabel");
  message_->setMinimumWidth(120);
  message_->setWordWrap(false);
  middle->addWidget(state_);
  middle->addWidget(message_);
  row->addLayout(middle, 1);
  progress_ = new QProgressBar(this);
  progress_->setObjectName("filterProgress");
  progress_->setRange(0, 100);
  progress_->setMaximumWidth(120);
  progress_->hide();
  row->addWidget(progress_);
  auto* right = new QVBoxLayout();
  homed_ = new QLabel(this);
  homed_->setObjectName("homedLabel");
  chain_ = new QLabel(this);
  chain_->setObjectName("chainLabel");
  stale_ = new QLabel(this);
  stale_->setObjectName("staleLabel");
  stale_->setWordWrap(true);
  stale_->hide();
  right->addWidget(homed_);
  right->addWidget(chain_);
  right->addWidget(stale_);
  row->addLayout(right);
  alarms_ = ui::button("No alarms", "alarmBadge", this);
  alarms_->setMinimumSize(110, 54);
  row->addWidget(alarms_);
  connect(alarms_, &QPushButton::clicked, this, &StatusStrip::alarmsClicked);

  connect(estop_, &QPushButton::clicked, this, [this]() {
    if (s_.connected && s_.status.task.state == ipc::TaskState::Estop) {
      s_.send(commands::set_state(ipc::TaskState::EstopReset), "E-stop reset");
    } else {
      s_.estop("E-stop");
    }
  });
  connect(machine_, &QPushButton::clicked, this, [this]() {
    refresh();
    const bool on = s_.connected && s_.status.task.state == ipc::TaskState::On;
    if (!on) s_.send(commands::set_state(ipc::TaskState::On), "machine on");
    else s_.send(commands::set_state(ipc::TaskState::Off), "machine off");
  });
  refresh();
}

void StatusStrip::show_message(const QString& text, bool warning) {
  const QString line = text.section('\n', 0, 0);
  ui::set_text(message_, message_->fontMetrics().elidedText(line, Qt::ElideRight, std::max(120, message_->width())));
  message_->setToolTip(text);
  ui::set_style(message_, warning ? "color: #b00000; font-weight: bold;" : "color: #204060;");
}

void StatusStrip::set_filter_progress(int percent) {
  progress_->setVisible(percent >= 0);
  if (percent >= 0) progress_->setValue(percent);
}

void StatusStrip::refresh() {
  const auto& st = s_.status;
  const bool c = s_.connected;
  const bool estop = !c || st.task.state == ipc::TaskState::Estop;
  ui::set_text(estop_, c && st.task.state == ipc::TaskState::Estop ? "E-STOP\nRESET" : "E-STOP");
  ui::set_style(estop_, c && st.task.state == ipc::TaskState::Estop
                            ? "QPushButton{background:#ffd400;color:#000;font-weight:bold;border:3px solid #c00000;}"
                            : "QPushButton{background:#d00000;color:#fff;font-weight:bold;border:3px solid #ffd400;}");
  estop_->setEnabled(c);
  const bool on = c && st.task.state == ipc::TaskState::On;
  machine_->setEnabled(c && !estop);
  machine_->setChecked(on);
  ui::set_text(machine_, on ? "MACHINE\nON" : "MACHINE\nOFF");
  ui::set_style(machine_, on ? "QPushButton{background:#208020;color:white;font-weight:bold;}" : "");
  for (int i = 0; i < 3; ++i) {
    QPushButton* b = modes_[static_cast<std::size_t>(i)];
    const bool active = c && st.task.mode == kModes[i];
    b->setChecked(active);
    b->setEnabled(c);
    ui::set_style(b, active ? "QPushButton{background:#1f4e9c;color:white;font-weight:bold;font-size:15px;}" : "");
  }
  QString state;
  if (!c) {
    state = "NO CONTROLLER";
  } else {
    state = QString("%1 · %2 · %3").arg(ipc::to_string(st.task.state), ipc::to_string(st.task.interp_state),
                                        ipc::to_string(st.task.exec_state));
    if (st.task.paused) state += " · PAUSED";
  }
  ui::set_text(state_, state);
  ui::set_style(state_, c ? "font-weight:bold;" : "font-weight:bold;color:#b00000;");
  const bool homed = s_.all_homed();
  ui::set_text(homed_, !c ? "" : homed ? "HOMED" : "NOT HOMED");
  ui::set_style(homed_, !c ? "" : homed ? "color:#208020;font-weight:bold;" : "color:white;background:#c00000;font-weight:bold;padding:2px;");
  ui::set_text(chain_, !c ? "" : st.io.estop_chain_ok ? "E-stop chain closed" : "E-stop chain OPEN");
  ui::set_style(chain_, !c ? "" : st.io.estop_chain_ok ? "color:#208020;" : "color:#b00000;font-weight:bold;");
  // A frozen status must not look like a live one.
  QString stale;
  if (c && s_.liveness.task_stalled) {
    stale = QString("TASK STALLED %1 s: status frozen, E-STOP still works")
                .arg(static_cast<double>(s_.liveness.status_age_ns) * 1e-9, 0, 'f', 1);
  }
  if (c && (s_.liveness.servo_stalled || st.motion.servo_stalled)) {
    stale += QString(stale.isEmpty() ? "" : "\n") + "MOTION NOT RUNNING: only the drives' watchdogs stop them";
  }
  ui::set_text(stale_, stale);
  ui::set_style(stale_, "color:white;background:#c00000;font-weight:bold;padding:2px;");
  stale_->setVisible(!stale.isEmpty());
  const std::size_t n = s_.alarms.active_count();
  ui::set_text(alarms_, n ? QString("ALARMS: %1").arg(n) : QString("No alarms"));
  ui::set_style(alarms_, n ? "QPushButton{background:#c00000;color:white;font-weight:bold;}" : "");
}

// ------------------------------------------------------------ DroPanel

DroPanel::DroPanel(Screen& s, QWidget* parent) : QWidget(parent), s_(s) {
  setObjectName("droPanel");
  auto* v = new QVBoxLayout(this);
  v->setContentsMargins(2, 2, 2, 2);
  units_ = new QLabel(this);
  units_->setObjectName("droUnits");
  units_->setStyleSheet("color: #404040;");
  actual_ = ui::button("Commanded", "droActual", this, true);
  actual_->setMinimumHeight(30);
  actual_->setToolTip("Show the commanded or the actual (feedback) position");
  actual_->setChecked(s_.show_actual);
  connect(actual_, &QPushButton::toggled, this, [this](bool on) {
    s_.show_actual = on;
    refresh();
  });
  auto* grid = new QGridLayout();
  grid->setHorizontalSpacing(6);
  grid->setVerticalSpacing(2);
  work_header_ = new QLabel("Work", this);
  grid->addWidget(units_, 0, 0, 1, 2);
  grid->addWidget(work_header_, 0, 2, Qt::AlignRight);
  machine_header_ = new QLabel("Machine", this);
  machine_header_->setObjectName("droMachineHeader");
  grid->addWidget(machine_header_, 0, 3, Qt::AlignRight);
  grid->addWidget(new QLabel("To go", this), 0, 4, Qt::AlignRight);
  grid->addWidget(actual_, 0, 5, 1, 3);
  const QString mono = "font-family: 'DejaVu Sans Mono', monospace;";
  std::vector<AxisConfig> axes = s_.config.axes;
  if (s_.config.lathe) {
    // Lathe: X (diameter/radius) then Z; Y is not shown unless configured.
    std::stable_sort(axes.begin(), axes.end(), [](const AxisConfig& a, const AxisConfig& b) {
      const auto rank = [](int i) { return i == 0 ? 0 : i == 2 ? 1 : i + 2; };
      return rank(a.index) < rank(b.index);
    });
  }
  int r = 1;
  for (const auto& ax : axes) {
    Row row{};
    row.axis = ax.index;
    const QString L(ax.letter);
    row.letter = new QLabel(L, this);
    row.letter->setStyleSheet("font-size: 22px; font-weight: bold;");
    row.marks = new QLabel(this);
    row.marks->setObjectName("droMarks_" + L);
    row.marks->setTextFormat(Qt::RichText);
    row.marks->setMinimumWidth(34);
    row.work = new QLabel(this);
    row.work->setObjectName("droWork_" + L);
    row.work->setStyleSheet(mono + "font-size: 22px; font-weight: bold;");
    row.work->setMinimumWidth(122);
    row.work->setAlignment(Qt::AlignRight | Qt::AlignVCenter);
    row.machine = new QLabel(this);
    row.machine->setObjectName("droMachine_" + L);
    row.machine->setStyleSheet(mono + "font-size: 14px;");
    row.machine->setAlignment(Qt::AlignRight | Qt::AlignVCenter);
    row.dtg = new QLabel(this);
    row.dtg->setObjectName("droDtg_" + L);
    row.dtg->setStyleSheet(mono + "font-size: 14px; color: #505050;");
    row.dtg->setAlignment(Qt::AlignRight | Qt::AlignVCenter);
    row.zero = ui::button("0", ("droZero_" + L).toLatin1().constData(), this);
    row.set = ui::button("=", ("droSet_" + L).toLatin1().constData(), this);
    row.home = ui::button("⌂", ("home_" + L).toLatin1().constData(), this);
    row.zero->setToolTip("Touch off: this position is 0 in the active work offset");
    row.set->setToolTip("Touch off: enter the value this position has");
    row.home->setToolTip("Home this axis");
    for (QPushButton* b : {row.zero, row.set, row.home}) b->setFixedWidth(ui::kTouch);
    grid->addWidget(row.letter, r, 0);
    grid->addWidget(row.marks, r, 1);
    grid->addWidget(row.work, r, 2);
    grid->addWidget(row.machine, r, 3);
    grid->addWidget(row.dtg, r, 4);
    grid->addWidget(row.zero, r, 5);
    grid->addWidget(row.set, r, 6);
    grid->addWidget(row.home, r, 7);
    const int axis = ax.index;
    connect(row.zero, &QPushButton::clicked, this, [this, axis]() { touch_off(axis, 0.0); });
    connect(row.set, &QPushButton::clicked, this, [this, axis]() { ask_touch_off(axis); });
    connect(row.home, &QPushButton::clicked, this, [this, axis]() {
      const auto joints = joints_of(axis);
      if (joints.empty()) {
        s_.log(LogLevel::Warning, std::string("axis ") + kAxisLetters[axis] + ": no joint known to home");
        return;
      }
      s_.send_in_mode(ipc::TaskMode::Manual, {commands::home(joints.front())}, std::string("home ") + kAxisLetters[axis]);
    });
    rows_.push_back(row);
    ++r;
  }
  grid->setColumnStretch(2, 3);
  grid->setColumnStretch(3, 2);
  grid->setColumnStretch(4, 2);
  v->addLayout(grid);
  info_ = new QLabel(this);
  info_->setObjectName("droInfo");
  info_->setStyleSheet("font-weight: bold;");
  info_->setWordWrap(true);
  gcodes_ = new QLabel(this);
  gcodes_->setObjectName("activeCodes");
  gcodes_->setWordWrap(true);
  gcodes_->setStyleSheet("color: #404040;");
  v->addWidget(info_);
  v->addWidget(gcodes_);
  refresh();
}

std::vector<int> DroPanel::joints_of(int axis) const {
  std::vector<int> out;
  if (s_.connected) {
    for (int j = 0; j < std::min<int>(s_.status.motion.joints, kMaxJoints); ++j) {
      if (s_.status.joints[j].axis == axis) out.push_back(j);
    }
  }
  if (out.empty()) {
    for (const auto& j : s_.config.joints) {
      if (j.axis == axis) out.push_back(j.index);
    }
  }
  return out;
}

void DroPanel::touch_off(int axis, double value) {
  if (!s_.connected) return;
  const auto& st = s_.status;
  if (s_.config.lathe && axis == 0 && diameter_mode(st)) value /= 2.0;  // X is shown as a diameter
  const Pose g5x = touch_off_offsets(st, axis, value, s_.show_actual);
  const int index = st.task.g5x_index;
  s_.send(commands::set_work_offset(index, g5x, st.task.rotation_xy),
          std::string("touch off ") + kAxisLetters[axis] + " in " + work_offset_name(index));
}

void DroPanel::ask_touch_off(int axis) {
  auto* dialog = new QInputDialog(this);
  dialog->setAttribute(Qt::WA_DeleteOnClose);
  dialog->setObjectName("touchOffDialog");
  dialog->setWindowTitle(QString("Touch off %1").arg(kAxisLetters[axis]));
  dialog->setLabelText(QString("%1 position in %2 (comma or point):")
                           .arg(kAxisLetters[axis])
                           .arg(ui::qs(work_offset_name(s_.status.task.g5x_index))));
  dialog->setTextValue("0");
  connect(dialog, &QInputDialog::textValueSelected, this, [this, axis](const QString& text) {
    std::string why;
    const auto v = parse_operator_number(text.toStdString(), &why);
    if (!v) {
      s_.log(LogLevel::Warning, "touch off: \"" + text.toStdString() + "\": " + why);
      return;
    }
    touch_off(axis, *v);
  });
  dialog->open();
}

void DroPanel::refresh() {
  const auto& st = s_.status;
  const bool c = s_.connected;
  const bool inch = c && program_inch(st);
  const bool m_inch = c ? machine_inch(st) : s_.config.machine_inch;
  const int dec = s_.config.dro_decimals(inch);
  const int mdec = s_.config.dro_decimals(m_inch);
  const DroPositions d = dro_positions(st, s_.show_actual);
  const bool diameter = s_.config.lathe && c && diameter_mode(st);
  ui::set_text(actual_, s_.show_actual ? "Actual" : "Commanded");
  ui::set_text(work_header_, QString("Work %1").arg(ui::qs(work_offset_name(c ? st.task.g5x_index : 1))));
  ui::set_text(units_, QString("%1 %2").arg(inch ? "inch" : "mm", inch ? "G20" : "G21"));
  ui::set_text(machine_header_, QString("Machine %1").arg(m_inch ? "in" : "mm"));
  units_->setToolTip(QString("Program units %1 (%2), machine units %3").arg(inch ? "inch" : "mm", inch ? "G20" : "G21", m_inch ? "inch" : "mm"));
  for (auto& r : rows_) {
    if (!c || !d.valid) {
      ui::set_text(r.work, c ? "unknown" : "—");
      ui::set_text(r.machine, "—");
      ui::set_text(r.dtg, "—");
    } else {
      const bool linear = is_linear_axis(r.axis);
      double work = d.work[r.axis];
      if (diameter && r.axis == 0) work *= 2.0;
      ui::set_text(r.work, s_.number(work, linear ? dec : 3));
      ui::set_text(r.machine, s_.number(d.machine[r.axis], linear ? mdec : 3));
      ui::set_text(r.dtg, s_.number(d.dtg[r.axis], linear ? dec : 3));
    }
    if (r.axis == 0 && s_.config.lathe) ui::set_text(r.letter, diameter ? "XØ" : "X");
    // Marks: homed, limits of the joints that move this axis.
    bool homed = c, homing = false, low = false, high = false, fault = false;
    const auto joints = joints_of(r.axis);
    if (joints.empty()) homed = false;
    for (int j : joints) {
      const auto& js = st.joints[j];
      homed = homed && js.homed;
      homing = homing || js.homing;
      low = low || js.min_hard_limit || js.min_soft_limit;
      high = high || js.max_hard_limit || js.max_soft_limit;
      fault = fault || js.fault;
    }
    QString marks = homing ? "<span style='color:#c08000'>◐</span>"
                           : homed ? "<span style='color:#208020'>●</span>" : "<span style='color:#c00000'>○</span>";
    if (low) marks += "<span style='color:#c00000;font-weight:bold'>-L</span>";
    if (high) marks += "<span style='color:#c00000;font-weight:bold'>+L</span>";
    if (fault) marks += "<span style='color:#c00000;font-weight:bold'>F</span>";
    ui::set_text(r.marks, marks);
    r.marks->setToolTip(homing ? "homing" : homed ? "homed" : "NOT homed");
    const bool idle_on = s_.is_on() && s_.is_idle();
    r.zero->setEnabled(idle_on && d.valid);
    r.set->setEnabled(idle_on && d.valid);
    r.home->setEnabled(idle_on);
  }
  if (!c) {
    ui::set_text(info_, "");
    ui::set_text(gcodes_, "");
    return;
  }
  const int tool = st.io.tool_in_spindle;
  QString info = QString("%1   %2").arg(ui::qs(work_offset_name(st.task.g5x_index)), ui::qs(s_.tool_text(tool)));
  bool tlo = false;
  for (int a = 0; a < kNumAxes; ++a) tlo = tlo || st.task.tool_offset[a] != 0;
  if (tlo) info += QString("   G43 Z%1").arg(s_.number(st.task.tool_offset[2], dec));
  else info += "   G49 (no tool length offset)";
  if (st.task.rotation_xy != 0) info += QString("   R%1°").arg(s_.number(st.task.rotation_xy, 3));
  ui::set_text(info_, info);
  QString codes;
  for (int g : st.task.active_gcodes) {
    if (g < 0) continue;
    codes += QString("G%1 ").arg(g % 10 ? QString("%1.%2").arg(g / 10).arg(g % 10) : QString::number(g / 10));
  }
  for (int m : st.task.active_mcodes) {
    if (m >= 0) codes += QString("M%1 ").arg(m);
  }
  codes += QString(" F%1 S%2").arg(s_.number(st.task.active_settings[1], 1), s_.number(st.task.active_settings[2], 0));
  ui::set_text(gcodes_, codes.trimmed());
}

// ------------------------------------------------------------ ManualPanel

ManualPanel::ManualPanel(Screen& s, QWidget* parent) : QWidget(parent), s_(s) {
  setObjectName("manualPanel");
  auto* v = new QVBoxLayout(this);
  v->setContentsMargins(2, 2, 2, 2);
  auto* top = new QHBoxLayout();
  home_all_ = ui::button("Home all", "homeAllButton", this);
  connect(home_all_, &QPushButton::clicked, this,
          [this]() { s_.send_in_mode(ipc::TaskMode::Manual, {commands::home(-1)}, "home all"); });
  top->addWidget(home_all_);
  // AXIS's "override limits": motion ignores the limit switches until the
  // end of the next jog, to jog off a switch it stopped on
  // (JointOverrideLimits, as `cnc override-limits`).
  override_limits_ = ui::button("Override\nlimits", "overrideLimitsButton", this, true);
  override_limits_->setToolTip(
      "Ignore the limit switches until the next jog ends: to jog off a limit switch the machine stopped on. "
      "Jog carefully, away from the switch; the switches are watched again after that jog.");
  connect(override_limits_, &QPushButton::clicked, this, [this]() {
    override_limits_->setChecked(true);  // shown from the status; cleared by motion after the jog
    s_.send_in_mode(ipc::TaskMode::Manual, {commands::override_limits()}, "override limits (until the next jog ends)");
  });
  top->addWidget(override_limits_);
  flood_ = ui::button("Flood", "floodButton", this, true);
  mist_ = ui::button("Mist", "mistButton", this, true);
  top->addWidget(flood_);
  top->addWidget(mist_);
  jog_note_ = new QLabel(this);
  jog_note_->setObjectName("jogNote");
  jog_note_->setWordWrap(true);
  top->addWidget(jog_note_, 1);
  v->addLayout(top);

  const auto add_increments = [&](const std::vector<Increment>& list, const char* prefix, bool angular) {
    auto* row = new QHBoxLayout();
    auto* group = new QButtonGroup(this);
    group->setExclusive(true);
    for (std::size_t i = 0; i < list.size(); ++i) {
      const QString name = QString("%1%2").arg(prefix).arg(i);
      auto* b = ui::button(list[i].continuous ? "Cont." : ui::qs(list[i].label), name.toLatin1().constData(), this, true);
      b->setMinimumWidth(40);
      group->addButton(b, static_cast<int>(i));
      row->addWidget(b);
    }
    group->button(0)->setChecked(true);
    connect(group, &QButtonGroup::idClicked, this, [this, angular](int id) {
      if (angular) s_.jog.select_angular_increment(id);
      else s_.jog.select_increment(id);
    });
    v->addLayout(row);
    return group;
  };
  increments_ = add_increments(s_.config.increments, "increment_", false);
  bool any_angular = false;
  for (const auto& a : s_.config.axes) any_angular = any_angular || a.angular;
  if (any_angular) angular_increments_ = add_increments(s_.config.angular_increments, "angularIncrement_", true);

  const auto add_speed = [&](double min, double max, double def, const char* name, QLabel*& label) {
    auto* row = new QHBoxLayout();
    auto* slider = new QSlider(Qt::Horizontal, this);
    slider->setObjectName(name);
    slider->setRange(static_cast<int>(std::floor(min * 60)), std::max(1, static_cast<int>(std::ceil(max * 60))));
    slider->setValue(static_cast<int>(std::lround(def * 60)));
    slider->setMinimumHeight(ui::kTouch - 8);
    slider->setFocusPolicy(Qt::NoFocus);
    label = new QLabel(this);
    label->setMinimumWidth(110);
    row->addWidget(new QLabel("Jog", this));
    row->addWidget(slider, 1);
    row->addWidget(label);
    v->addLayout(row);
    return slider;
  };
  speed_ = add_speed(s_.config.min_linear_velocity, s_.config.max_linear_velocity, s_.config.default_linear_velocity,
                     "jogSpeed", speed_label_);
  s_.jog.set_linear_velocity(speed_->value() / 60.0);
  connect(speed_, &QSlider::valueChanged, this, [this](int v) {
    s_.jog.set_linear_velocity(v / 60.0);
    set_speed_label();
  });
  if (any_angular) {
    angular_speed_ = add_speed(s_.config.min_angular_velocity, s_.config.max_angular_velocity,
                               s_.config.default_angular_velocity, "jogAngularSpeed", angular_speed_label_);
    s_.jog.set_angular_velocity(angular_speed_->value() / 60.0);
    connect(angular_speed_, &QSlider::valueChanged, this, [this](int v) {
      s_.jog.set_angular_velocity(v / 60.0);
      set_speed_label();
    });
  }
  set_speed_label();

  // Jog buttons: one row per axis (lathe: Z then X, as the machine is seen).
  auto* grid = new QGridLayout();
  std::vector<AxisConfig> axes = s_.config.axes;
  if (s_.config.lathe) {
    std::stable_sort(axes.begin(), axes.end(), [](const AxisConfig& a, const AxisConfig& b) {
      return (a.index == 2 ? -1 : a.index) < (b.index == 2 ? -1 : b.index);
    });
  }
  int col = 0, row = 0;
  for (const auto& ax : axes) {
    for (int dir : {-1, 1}) {
      const QString name = QString("jog%1_%2").arg(dir < 0 ? "Minus" : "Plus").arg(ax.letter);
      auto* b = ui::button(QString("%1%2").arg(ax.letter).arg(dir < 0 ? "−" : "+"), name.toLatin1().constData(), this);
      b->setAutoRepeat(false);
      const int axis = ax.index;
      connect(b, &QPushButton::pressed, this, [this, axis, dir]() {
        if (s_.is_on() && s_.is_idle() && s_.status.task.mode != ipc::TaskMode::Manual) {
          s_.send_in_mode(ipc::TaskMode::Manual, {}, "mode MANUAL for jogging");
          s_.log(LogLevel::Info, "switched to MANUAL for jogging: press the jog button again");
          return;
        }
        if (!s_.jog.press(axis, dir, JogController::Source::Button) && !s_.jog.why_not().empty()) {
          s_.log(LogLevel::Warning, "jog: " + s_.jog.why_not());
        }
      });
      connect(b, &QPushButton::released, this, [this, axis]() { s_.jog.release(axis, JogController::Source::Button); });
      grid->addWidget(b, row, col + (dir < 0 ? 0 : 1));
      jog_buttons_.push_back(b);
    }
    col += 2;
    if (col >= (axes.size() <= 3 ? 6 : 4)) {
      col = 0;
      ++row;
    }
  }
  v->addLayout(grid);

  // Spindle and coolant.
  auto* sp = new QHBoxLayout();
  auto* rev = ui::button("⟲ REV", "spindleReverse", this);
  auto* stop = ui::button("■", "spindleStop", this);
  auto* fwd = ui::button("FWD ⟳", "spindleForward", this);
  auto* slower = ui::button("−", "spindleSlower", this);
  auto* faster = ui::button("+", "spindleFaster", this);
  for (auto* b : {stop, slower, faster}) b->setFixedWidth(ui::kTouch);
  rpm_ = new QLineEdit(QString::number(s_.config.default_spindle_speed), this);
  rpm_->setObjectName("spindleRpm");
  rpm_->setMaximumWidth(70);
  rpm_->setFocusPolicy(Qt::ClickFocus);  // never takes the keys from jogging by itself
  rpm_->setMinimumHeight(ui::kTouch - 8);
  const auto start = [this](int dir) {
    std::string why;
    const auto v = parse_operator_number(rpm_->text().toStdString(), &why);
    if (!v || *v <= 0) {
      s_.log(LogLevel::Warning, "spindle speed \"" + rpm_->text().toStdString() + "\": " + (v ? "must be above 0" : why));
      return;
    }
    s_.send(commands::spindle_on(dir * *v), dir > 0 ? "spindle forward" : "spindle reverse");
  };
  connect(fwd, &QPushButton::clicked, this, [start]() { start(1); });
  connect(rev, &QPushButton::clicked, this, [start]() { start(-1); });
  connect(stop, &QPushButton::clicked, this, [this]() { s_.send(commands::spindle_off(), "spindle stop"); });
  connect(slower, &QPushButton::clicked, this, [this]() { s_.send(commands::spindle_slower(), "spindle slower"); });
  connect(faster, &QPushButton::clicked, this, [this]() { s_.send(commands::spindle_faster(), "spindle faster"); });
  sp->addWidget(rev);
  sp->addWidget(stop);
  sp->addWidget(fwd);
  sp->addWidget(slower);
  sp->addWidget(faster);
  sp->addWidget(rpm_);
  sp->addWidget(new QLabel("rpm", this));
  v->addLayout(sp);
  connect(flood_, &QPushButton::clicked, this, [this]() {
    const bool want = !s_.status.io.flood;
    refresh();
    s_.send(commands::flood(want), want ? "flood on" : "flood off");
  });
  connect(mist_, &QPushButton::clicked, this, [this]() {
    const bool want = !s_.status.io.mist;
    refresh();
    s_.send(commands::mist(want), want ? "mist on" : "mist off");
  });
  refresh();
}

void ManualPanel::set_speed_label() {
  const QString u = s_.config.machine_inch ? "in/min" : "mm/min";
  ui::set_text(speed_label_, QString("%1 %2").arg(speed_->value()).arg(u));
  if (angular_speed_) ui::set_text(angular_speed_label_, QString("%1 °/min").arg(angular_speed_->value()));
}

void ManualPanel::refresh() {
  const auto& st = s_.status;
  const bool ok = s_.is_on() && s_.is_idle();
  home_all_->setEnabled(ok);
  ui::set_style(home_all_, ok && !s_.all_homed() ? "QPushButton{background:#ffd400;font-weight:bold;}" : "");
  for (auto* b : jog_buttons_) b->setEnabled(ok);
  bool overridden = false, on_switch = false;
  for (int j = 0; j < st.motion.joints && j < kMaxJoints; ++j) {
    overridden = overridden || st.joints[j].override_limits;
    on_switch = on_switch || st.joints[j].min_hard_limit || st.joints[j].max_hard_limit;
  }
  const bool can_override = s_.connected && st.task.state == ipc::TaskState::On && s_.is_idle();
  override_limits_->setChecked(s_.connected && overridden);
  override_limits_->setEnabled(can_override && !overridden);
  ui::set_style(override_limits_, overridden ? "QPushButton{background:#ffd400;color:black;font-weight:bold;}" : "");
  QString note;
  if (!s_.connected) note = "";
  else if (overridden) note = "LIMITS OVERRIDDEN until the next jog ends: jog off the switch";
  else if (on_switch) note = "on a limit switch: press Override limits, then jog off it";
  else if (!s_.jog.can_jog()) note = ui::qs(s_.jog.why_not());
  else if (s_.jog.joint_mode()) note = "not homed: jogging joints";
  if (!s_.jog.keyboard_enabled()) note += note.isEmpty() ? "keyboard jog off (text field)" : " · keyboard jog off";
  ui::set_text(jog_note_, note);
  // The increment buttons follow the controller's choice (a stop may have
  // been forced); keep them in step with the jog state machine.
  if (increments_->checkedId() != s_.jog.increment_index()) increments_->button(s_.jog.increment_index())->setChecked(true);
  flood_->setChecked(s_.connected && st.io.flood);
  mist_->setChecked(s_.connected && st.io.mist);
  flood_->setEnabled(s_.is_on());
  mist_->setEnabled(s_.is_on());
}

// ------------------------------------------------------------ OverridePanel

namespace {
const char* kOvNames[4] = {"feedOverride", "rapidOverride", "spindleOverride", "maxVelocity"};
const char* kOvLabels[4] = {"Feed", "Rapid", "Spindle", "Max vel."};
}  // namespace

OverridePanel::OverridePanel(Screen& s, QWidget* parent) : QWidget(parent), s_(s) {
  setObjectName("overridePanel");
  auto* grid = new QGridLayout(this);
  grid->setContentsMargins(2, 2, 2, 2);
  grid->setVerticalSpacing(2);
  const auto& c = s_.config;
  const int ranges[4][2] = {
      {0, static_cast<int>(std::lround(c.max_feed_override * 100))},
      {0, static_cast<int>(std::lround(c.max_rapid_override * 100))},
      {static_cast<int>(std::lround(c.min_spindle_override * 100)), static_cast<int>(std::lround(c.max_spindle_override * 100))},
      {0, std::max(1, static_cast<int>(std::lround(c.trajectory_max_velocity > 0 ? c.trajectory_max_velocity * 60 : c.max_linear_velocity * 60)))},
  };
  for (int i = 0; i < 4; ++i) {
    Ov& o = ov_[static_cast<std::size_t>(i)];
    o.slider = new QSlider(Qt::Horizontal, this);
    o.slider->setObjectName(kOvNames[i]);
    o.slider->setRange(ranges[i][0], ranges[i][1]);
    o.slider->setValue(i == 3 ? ranges[i][1] : std::clamp(100, ranges[i][0], ranges[i][1]));
    o.slider->setMinimumHeight(ui::kTouch - 10);
    o.slider->setFocusPolicy(Qt::NoFocus);
    o.label = new QLabel(this);
    o.label->setMinimumWidth(92);
    auto* reset = ui::button(i == 3 ? "Max" : "100%", (std::string(kOvNames[i]) + "Reset").c_str(), this);
    reset->setFixedWidth(56);
    grid->addWidget(new QLabel(kOvLabels[i], this), i, 0);
    grid->addWidget(o.slider, i, 1);
    grid->addWidget(o.label, i, 2);
    grid->addWidget(reset, i, 3);
    connect(o.slider, &QSlider::valueChanged, this, [this, i](int v) { changed(i, v); });
    connect(o.slider, &QSlider::sliderReleased, this, [this, i]() { send(i, ov_[static_cast<std::size_t>(i)].slider->value()); });
    connect(reset, &QPushButton::clicked, this, [this, i]() {
      QSlider* sl = ov_[static_cast<std::size_t>(i)].slider;
      const int v = i == 3 ? sl->maximum() : std::clamp(100, sl->minimum(), sl->maximum());
      sl->setValue(v);
      send(i, v);
    });
    o.label->setText(text(i, o.slider->value()));
  }
  effective_ = new QLabel(this);
  effective_->setObjectName("effectiveFeed");
  effective_->setWordWrap(true);  // the readouts are long: they wrap in a narrow window
  grid->addWidget(effective_, 4, 0, 1, 4);
  grid->setColumnStretch(1, 1);
}

QString OverridePanel::text(int which, int value) const {
  if (which == 3) return QString("%1 %2").arg(value).arg(s_.config.machine_inch ? "in/min" : "mm/min");
  return QString("%1 %").arg(value);
}

void OverridePanel::changed(int which, int value) {
  Ov& o = ov_[static_cast<std::size_t>(which)];
  ui::set_text(o.label, text(which, value));
  if (o.slider->isSliderDown()) o.pending = value;  // sent once a cycle while dragging
  else if (value != static_cast<int>(std::lround(status_value(which)))) send(which, value);
}

void OverridePanel::send(int which, int value) {
  ov_[static_cast<std::size_t>(which)].pending = -1;
  switch (which) {
    case 0: s_.send(commands::feed_override(value / 100.0), "feed override"); break;
    case 1: s_.send(commands::rapid_override(value / 100.0), "rapid override"); break;
    case 2: s_.send(commands::spindle_override(value / 100.0), "spindle override"); break;
    case 3: s_.send(commands::max_velocity(value / 60.0), "maximum velocity"); break;
    default: break;
  }
}

void OverridePanel::flush() {
  for (int i = 0; i < 4; ++i) {
    if (ov_[static_cast<std::size_t>(i)].pending >= 0) send(i, ov_[static_cast<std::size_t>(i)].pending);
  }
}

double OverridePanel::status_value(int which) const {
  const auto& st = s_.status;
  switch (which) {
    case 0: return st.motion.feed_scale * 100;
    case 1: return st.motion.rapid_scale * 100;
    case 2: return st.spindles[0].override_scale * 100;
    case 3: {
      const double max = ov_[3].slider->maximum();
      const double v = st.motion.max_velocity * 60;
      return v <= 0 || v > max ? max : v;
    }
    default: return 0;
  }
}

void OverridePanel::refresh() {
  if (!s_.connected) return;
  // The path limit in force is motion's (the INI's, as changed at run time
  // with `cnc set traj.max-velocity`): it bounds the max-velocity slider.
  const double path_max = s_.status.motion.max_linear_velocity;
  if (path_max > 0 && path_max < 1e98) {
    const int top = std::max(1, static_cast<int>(std::lround(path_max * 60)));
    if (ov_[3].slider->maximum() != top) {
      const QSignalBlocker block(ov_[3].slider);
      ov_[3].slider->setMaximum(top);
    }
  }
  for (int i = 0; i < 4; ++i) {
    Ov& o = ov_[static_cast<std::size_t>(i)];
    o.slider->setEnabled(true);
    if (o.slider->isSliderDown() || o.pending >= 0) continue;
    const int v = static_cast<int>(std::lround(status_value(i)));
    if (o.slider->value() != v) {
      const QSignalBlocker block(o.slider);
      o.slider->setValue(v);
      ui::set_text(o.label, text(i, v));
    }
  }
  // The executing line's F and S, with units, the override, and the
  // spindle's actual speed from its feedback (hmi/readouts.hpp).
  const auto& st = s_.status;
  ui::set_text(effective_, ui::qs(feed_readout(st, s_.config.machine_inch, s_.numbers)) + "\n" +
                               ui::qs(spindle_readout(st, s_.numbers)));
}

}  // namespace cnc::hmi
