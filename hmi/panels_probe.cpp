// The Probe page: probing routines (hmi/probing.hpp) and touch-off into any
// coordinate system.
#include <QComboBox>
#include <QFormLayout>
#include <QGroupBox>
#include <QHBoxLayout>
#include <QLabel>
#include <QLineEdit>
#include <QPushButton>
#include <QSpinBox>
#include <QVBoxLayout>
#include <algorithm>

#include "hmi/panels.hpp"

namespace cnc::hmi {

namespace {

struct Choice {
  const char* label;
  probing::Kind kind;
  int axis;
  int direction;
};
const Choice kChoices[] = {
    {"Tool length on the tool setter", probing::Kind::ToolLength, 2, -1},
    {"Edge X+ (probe moves toward +X)", probing::Kind::Edge, 0, 1},
    {"Edge X- (probe moves toward -X)", probing::Kind::Edge, 0, -1},
    {"Edge Y+ (probe moves toward +Y)", probing::Kind::Edge, 1, 1},
    {"Edge Y- (probe moves toward -Y)", probing::Kind::Edge, 1, -1},
    {"Inside corner", probing::Kind::InsideCorner, 0, 1},
    {"Outside corner", probing::Kind::OutsideCorner, 0, 1},
    {"Bore centre (start inside the bore)", probing::Kind::Bore, 0, 1},
    {"Boss centre (start above the boss)", probing::Kind::Boss, 0, 1},
    {"Tip calibration (start inside a ring gauge)", probing::Kind::TipCalibration, 0, 1},
};

QLineEdit* number_field(QWidget* parent, const char* name, const QString& text) {
  auto* e = new QLineEdit(text, parent);
  e->setObjectName(name);
  e->setMinimumHeight(ui::kTouch);
  return e;
}

// Combo boxes as narrow as a few characters: the page fits 1024 px.
QComboBox* narrow_combo(QWidget* parent) {
  auto* c = new QComboBox(parent);
  c->setSizeAdjustPolicy(QComboBox::AdjustToMinimumContentsLengthWithIcon);
  c->setMinimumContentsLength(8);
  c->setMinimumHeight(ui::kTouch);
  return c;
}

QComboBox* systems(QWidget* parent, const char* name, bool with_none) {
  auto* c = narrow_combo(parent);
  c->setObjectName(name);
  c->setMinimumHeight(ui::kTouch);
  if (with_none) c->addItem("measure only", 0);
  for (int i = 1; i <= 9; ++i) c->addItem(QString::fromStdString(probing::coordinate_system_name(i)), i);
  return c;
}

}  // namespace

ProbePage::ProbePage(Screen& s, QWidget* parent) : QWidget(parent), s_(s), probe_(s.config.probe) {
  setObjectName("probePage");
  auto* v = new QVBoxLayout(this);
  auto* top = new QHBoxLayout();
  v->addLayout(top, 1);

  auto* routine_box = new QGroupBox("Probing routine", this);
  top->addWidget(routine_box, 3);
  auto* form = new QFormLayout(routine_box);
  kind_ = narrow_combo(routine_box);
  kind_->setObjectName("probeRoutine");
  kind_->setMinimumHeight(ui::kTouch);
  for (const auto& c : kChoices) kind_->addItem(c.label);
  form->addRow("Routine", kind_);
  tool_ = new QSpinBox(routine_box);
  tool_->setObjectName("probeTool");
  tool_->setRange(1, 99999);
  tool_->setMinimumHeight(ui::kTouch);
  form->addRow("Tool", tool_);
  corner_x_ = narrow_combo(routine_box);
  corner_x_->setObjectName("probeCornerX");
  corner_x_->addItem("material toward +X", 1);
  corner_x_->addItem("material toward -X", -1);
  corner_y_ = narrow_combo(routine_box);
  corner_y_->setObjectName("probeCornerY");
  corner_y_->addItem("material toward +Y", 1);
  corner_y_->addItem("material toward -Y", -1);
  form->addRow("Corner X", corner_x_);
  form->addRow("Corner Y", corner_y_);
  corner_step_ = number_field(routine_box, "probeCornerStep", "10");
  form->addRow("Step along faces", corner_step_);
  boss_diameter_ = number_field(routine_box, "probeBossDiameter", "20");
  boss_depth_ = number_field(routine_box, "probeBossDepth", "5");
  // Diameter and depth on one row: the page fits a 1024x768 screen.
  auto* boss_row = new QHBoxLayout();
  boss_row->addWidget(boss_diameter_);
  boss_row->addWidget(new QLabel("depth", routine_box));
  boss_row->addWidget(boss_depth_);
  form->addRow("Boss Ø (about)", boss_row);
  gauge_diameter_ = number_field(routine_box, "probeGaugeDiameter", "20");
  form->addRow("Ring gauge Ø", gauge_diameter_);
  system_ = systems(routine_box, "probeSystem", true);
  form->addRow("Set origin in", system_);
  value_x_ = number_field(routine_box, "probeValueX", "0");
  value_y_ = number_field(routine_box, "probeValueY", "0");
  form->addRow("Result reads X", value_x_);
  form->addRow("Result reads Y", value_y_);
  auto* buttons = new QHBoxLayout();
  start_ = ui::button("Start probing", "probeStart", routine_box);
  stop_ = ui::button("Stop", "probeStop", routine_box);
  start_->setStyleSheet("QPushButton:enabled{background:#2a8a2a;color:white;font-weight:bold;}");
  stop_->setStyleSheet("QPushButton{background:#a02020;color:white;font-weight:bold;}");
  buttons->addWidget(start_);
  buttons->addWidget(stop_);
  form->addRow(buttons);

  auto* right = new QVBoxLayout();
  top->addLayout(right, 2);
  auto* touch_box = new QGroupBox("Touch off (any G54…G59.3)", this);
  right->addWidget(touch_box);
  auto* tform = new QFormLayout(touch_box);
  touch_axis_ = narrow_combo(touch_box);
  touch_axis_->setObjectName("touchAxis");
  touch_axis_->setMinimumHeight(ui::kTouch);
  for (const auto& a : s_.config.axes) touch_axis_->addItem(QString(a.letter), a.index);
  tform->addRow("Axis", touch_axis_);
  touch_system_ = systems(touch_box, "touchSystem", false);
  tform->addRow("System", touch_system_);
  touch_value_ = number_field(touch_box, "touchValue", "0");
  tform->addRow("Reads", touch_value_);
  touch_button_ = ui::button("Touch off", "touchOffButton", touch_box);
  tform->addRow(touch_button_);
  settings_ = new QLabel(this);
  settings_->setObjectName("probeSettings");
  settings_->setWordWrap(true);
  right->addWidget(settings_);
  right->addStretch(1);

  stage_ = new QLabel(this);
  stage_->setObjectName("probeStage");
  stage_->setWordWrap(true);
  v->addWidget(stage_);
  result_ = new QLabel("No result yet", this);
  result_->setObjectName("probeResult");
  result_->setWordWrap(true);
  result_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  result_->setStyleSheet("QLabel{font-size:14pt;font-weight:bold;}");
  v->addWidget(result_);

  show_settings();

  connect(kind_, &QComboBox::currentIndexChanged, this, [this](int) { update_fields(); });
  connect(start_, &QPushButton::clicked, this, [this]() { start(); });
  connect(stop_, &QPushButton::clicked, this, [this]() {
    s_.jog.stop_all();
    s_.send(commands::abort(), "probing: stop");
    if (routine_) {
      routine_->fail("stopped by the operator");
      finished();
    }
  });
  connect(touch_button_, &QPushButton::clicked, this, [this]() { touch_off(); });
  update_fields();
}

ProbePage::~ProbePage() = default;

void ProbePage::show_settings() {
  const auto& p = probe_;
  const QString u = s_.config.machine_inch ? "in" : "mm";
  QString text = QString("[PROBE] tip %1 %2 · search %3 %2 at %4 %2/min · latch %5 %2 at %6 %2/min · clearance %7 %2")
                     .arg(p.tip_diameter)
                     .arg(u)
                     .arg(p.search_distance)
                     .arg(p.search_feed)
                     .arg(p.latch_distance)
                     .arg(p.latch_feed)
                     .arg(p.clearance);
  if (p.tip_diameter != s_.config.probe.tip_diameter) {
    text += QString(" (calibrated; [PROBE]TIP_DIAMETER = %1 keeps it)").arg(p.tip_diameter, 0, 'f', 4);
  }
  text += p.setter ? QString("\nTool setter at machine X %1 Y %2, search from Z %3 over %4 %5; reference Z %6 (length 0)")
                         .arg(p.setter_x)
                         .arg(p.setter_y)
                         .arg(p.setter_z)
                         .arg(p.setter_search_distance)
                         .arg(u)
                         .arg(p.setter_reference_z)
                   : QString("\nNo tool setter configured ([PROBE]SETTER_X/Y/Z, SETTER_REFERENCE_Z)");
  text += "\nThe routines save the modal state (M70) and restore it at the end (M72). Results are machine coordinates.";
  ui::set_text(settings_, text);
}

bool ProbePage::running() const { return routine_ != nullptr; }

void ProbePage::update_fields() {
  const auto kind = kChoices[std::max(0, kind_->currentIndex())].kind;
  const bool corner = kind == probing::Kind::InsideCorner || kind == probing::Kind::OutsideCorner;
  tool_->setEnabled(kind == probing::Kind::ToolLength);
  corner_x_->setEnabled(corner);
  corner_y_->setEnabled(corner);
  corner_step_->setEnabled(kind == probing::Kind::OutsideCorner);
  boss_diameter_->setEnabled(kind == probing::Kind::Boss);
  boss_depth_->setEnabled(kind == probing::Kind::Boss);
  gauge_diameter_->setEnabled(kind == probing::Kind::TipCalibration);
  system_->setEnabled(kind != probing::Kind::ToolLength);
  const auto& ch = kChoices[std::max(0, kind_->currentIndex())];
  value_x_->setEnabled(kind != probing::Kind::ToolLength && (kind != probing::Kind::Edge || ch.axis == 0));
  value_y_->setEnabled(kind != probing::Kind::ToolLength && (kind != probing::Kind::Edge || ch.axis == 1));
}

bool ProbePage::start() {
  const auto refuse = [this](const std::string& why) {
    ui::set_text(result_, QString::fromStdString("Not started: " + why));
    s_.log(LogLevel::Warning, "probing not started: " + why);
    return false;
  };
  if (routine_) return refuse("a routine is running");
  if (!s_.is_on()) return refuse("the machine is not on");
  if (!s_.all_homed()) return refuse("not every joint is homed");
  if (!s_.is_idle()) return refuse("the controller is busy");
  const auto& ch = kChoices[std::max(0, kind_->currentIndex())];
  probing::Request q;
  q.kind = ch.kind;
  q.axis = ch.axis;
  q.direction = ch.direction;
  q.tool = tool_->value();
  q.corner_x = corner_x_->currentData().toInt();
  q.corner_y = corner_y_->currentData().toInt();
  q.coordinate_system = system_->isEnabled() ? system_->currentData().toInt() : 0;
  const auto number = [&](QLineEdit* e, const char* what, double& out) {
    if (!e->isEnabled()) return true;
    std::string why;
    const auto v = parse_operator_number(e->text().toStdString(), &why);
    if (!v) {
      refuse(std::string(what) + ": " + why);
      return false;
    }
    out = *v;
    return true;
  };
  if (!number(corner_step_, "step along faces", q.corner_step) || !number(boss_diameter_, "boss diameter", q.boss_diameter) ||
      !number(boss_depth_, "boss depth", q.boss_depth) || !number(value_x_, "X value", q.value_x) ||
      !number(value_y_, "Y value", q.value_y) || !number(gauge_diameter_, "ring gauge diameter", q.gauge_diameter)) {
    return false;
  }
  const probing::Start start = probing::start_from(s_.status);
  try {
    routine_ = std::make_unique<probing::Routine>(probe_, q, start);
  } catch (const std::invalid_argument& e) {
    return refuse(e.what());
  }
  s_.log(LogLevel::Info, std::string("probing: ") + probing::to_string(q.kind) + " started");
  ui::set_text(result_, "Probing…");
  send_stage();
  return true;
}

void ProbePage::send_stage() {
  if (!routine_) return;
  if (routine_->done()) {
    finished();
    return;
  }
  const probing::Stage& st = routine_->stage();
  std::vector<ipc::Command> cmds;
  for (const auto& line : st.lines) cmds.push_back(commands::mdi(line));
  ui::set_text(stage_, QString::fromStdString("Stage: " + st.what));
  s_.send_in_mode(ipc::TaskMode::Mdi, std::move(cmds), "probing: " + st.what, [this](const ipc::CommandResult& r) {
    if (!routine_) return;
    if (r.state != ipc::CommandState::Done) {
      routine_->fail(routine_->stage().what + ": " + (r.reason.empty() ? std::string("refused") : std::string(r.reason.view())));
      finished();
      return;
    }
    wait_cycles_ = 2;  // read the probe from a status taken after this answer
  });
}

void ProbePage::refresh() {
  const bool can = s_.is_on() && s_.all_homed();
  start_->setEnabled(can && !routine_ && (s_.is_idle() || s_.status.task.mode == ipc::TaskMode::Mdi));
  stop_->setEnabled(s_.connected);
  touch_button_->setEnabled(can && !routine_ && s_.is_idle());
  if (!routine_ || wait_cycles_ <= 0) return;
  if (--wait_cycles_ > 0) return;
  routine_->completed(s_.status.motion.probe_tripped, s_.status.motion.probed_position);
  send_stage();
}

void ProbePage::finished() {
  if (!routine_) return;
  if (routine_->failed()) {
    ui::set_text(result_, QString::fromStdString("Failed: " + routine_->error()));
    s_.log(LogLevel::Error, "probing: " + routine_->error());
    std::vector<ipc::Command> cmds;
    for (const auto& line : routine_->cleanup_lines()) cmds.push_back(commands::mdi(line));
    if (s_.is_on()) s_.send_in_mode(ipc::TaskMode::Mdi, std::move(cmds), "probing: the modal state of the start");
  } else {
    if (routine_->result().tip_diameter > 0) {
      probe_.tip_diameter = routine_->result().tip_diameter;  // the edges, corners and centres from now on
      show_settings();
    }
    ui::set_text(result_, QString::fromStdString(routine_->result().summary));
    s_.log(LogLevel::Info, "probing: " + routine_->result().summary);
  }
  ui::set_text(stage_, "");
  wait_cycles_ = 0;
  routine_.reset();
}

void ProbePage::touch_off() {
  std::string why;
  const auto v = parse_operator_number(touch_value_->text().toStdString(), &why);
  if (!v) {
    s_.log(LogLevel::Warning, "touch off: " + why);
    return;
  }
  const std::string line =
      probing::touch_off_line(touch_system_->currentData().toInt(), touch_axis_->currentData().toInt(), *v);
  s_.send_in_mode(ipc::TaskMode::Mdi, {commands::mdi(line)}, "touch off " + line);
}

}  // namespace cnc::hmi
