// The nine pages of the wizard: each collects its inputs, runs the step's
// subcommand through StepPage::run and shows what the state holds after it.
#include <QCheckBox>
#include <QComboBox>
#include <QDir>
#include <QFile>
#include <QFileInfo>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QLabel>
#include <QLineEdit>
#include <QListWidget>
#include <QMessageBox>
#include <QPlainTextEdit>
#include <QPushButton>
#include <QSpinBox>
#include <QTextEdit>
#include <QVBoxLayout>
#include <QtCharts/QChart>
#include <QtCharts/QChartView>
#include <QtCharts/QLineSeries>
#include <QtCharts/QLogValueAxis>
#include <QtCharts/QValueAxis>
#include <cmath>

#include "commission/response.hpp"
#include "commission/scan.hpp"
#include "commission/steps.hpp"  // machine_joints
#include "commission/wizard/wizard_window.hpp"

namespace cnc::commission::wizard {

namespace {

QPushButton* button(const QString& text, const char* name) {
  auto* b = new QPushButton(text);
  b->setObjectName(name);
  return b;
}

QDoubleSpinBox* number(const char* name, double min, double max, double value, int decimals, const QString& suffix) {
  auto* s = new QDoubleSpinBox;
  s->setObjectName(name);
  s->setRange(min, max);
  s->setDecimals(decimals);
  s->setValue(value);
  s->setSuffix(suffix);
  return s;
}

QLineEdit* line(const char* name, const QString& text = "", const QString& placeholder = "") {
  auto* l = new QLineEdit(text);
  l->setObjectName(name);
  l->setPlaceholderText(placeholder);
  return l;
}

// The axis chooser of pages 3-8: the axes of the state.
QComboBox* axis_choice() {
  auto* c = new QComboBox;
  c->setObjectName("axisLetter");
  return c;
}

void fill_axes(QComboBox* c, const State& s) {
  const QString keep = c->currentText();
  c->clear();
  for (const auto& a : s.axes) c->addItem(QString(QChar(a.letter)));
  if (c->count() == 0) c->addItem("X");
  const int i = c->findText(keep);
  if (i >= 0) c->setCurrentIndex(i);
}

char letter_of(const QComboBox* c) {
  const QString t = c->currentText();
  return t.isEmpty() ? '?' : t.at(0).toLatin1();
}

QSpinBox* count(const char* name, int min, int max, int value) {
  auto* s = new QSpinBox;
  s->setObjectName(name);
  s->setRange(min, max);
  s->setValue(value);
  return s;
}

QLabel* shown(const char* name) {
  auto* l = new QLabel;
  l->setObjectName(name);
  l->setWordWrap(true);
  l->setTextInteractionFlags(Qt::TextSelectableByMouse);
  return l;
}

// One row of a form: the widgets side by side, the first one stretched
// when `stretch_first`.
QHBoxLayout* row(std::initializer_list<QWidget*> widgets, bool stretch_first = false) {
  auto* r = new QHBoxLayout;
  bool first = true;
  for (QWidget* w : widgets) {
    r->addWidget(w, first && stretch_first ? 1 : 0);
    first = false;
  }
  return r;
}

QString mm(double v) { return QString::number(v, 'f', 3); }

// The pages of one axis (3-8): the axis chooser on top of a form (in a
// column, so a page can add a plot below); what the state holds for the
// chosen axis is shown by show_axis() after every reload and change of
// axis. The motion steps (5-8) can run on a controller of their own
// (`--bring-up` into the wizard's configuration folder, shut down after
// the step), which homing and tuning need: their configuration differs
// from the state's.
class AxisPage : public StepPage {
 public:
  AxisPage(WizardWindow& w, int step, const QString& intro, bool motion) : StepPage(w, step, intro) {
    column_ = new QVBoxLayout(inputs());
    form_ = new QFormLayout;
    column_->addLayout(form_);
    form_->addRow("Axis", axis_ = axis_choice());
    if (motion) {
      own_ = new QCheckBox("on a controller of its own, brought up in the configuration folder for the step "
                           "(shut down the running one first: page 4)");
      own_->setObjectName("ownController");
      own_->setChecked(true);
      form_->addRow("Controller", own_);
    }
    connect(axis_, &QComboBox::currentIndexChanged, this, [this] { show_axis(w_.state()); });
  }
  void refresh(const State& s) override {
    fill_axes(axis_, s);
    show_axis(s);
  }

 protected:
  virtual void show_axis(const State&) {}
  char letter() const { return letter_of(axis_); }
  const Axis* axis(const State& s) const { return s.axis(letter()); }
  // The --bring-up folder of a motion step ("" on the running controller).
  std::string bring_up() const {
    return own_ && own_->isChecked() ? w_.options().config_dir.toStdString() : std::string();
  }
  QVBoxLayout* column_;
  QFormLayout* form_;
  QComboBox* axis_;
  QCheckBox* own_ = nullptr;
};

// ------------------------------------------------------------ 1 bus

class BusPage : public StepPage {
 public:
  explicit BusPage(WizardWindow& w)
      : StepPage(w, 0,
                 "Scan the bus: every CANopen node 1-127 (identity, name, firmware, CiA 402 modes) or every "
                 "EtherCAT slave (SII identity), each matched with a description file (EDS/ESI) of the folder.") {
    auto* f = new QFormLayout(inputs());
    kind_ = new QComboBox;
    kind_->setObjectName("busKind");
    kind_->addItems({"CANopen", "EtherCAT"});
    f->addRow("Bus", kind_);
    f->addRow("Interface", iface_ = line("busInterface", "", "socketcan:can0 or raw:eth0"));
    f->addRow("EDS/ESI folder", dir_ = line("descriptionDir"));
    f->addRow("Expected node-IDs", expect_ = line("expectNodes", "", "1,2,3 (optional)"));
    auto* b = button("Scan", "scanButton");
    f->addRow(b);
    // Drives that come without node-ID get free ones by LSS (CANopen).
    first_ = count("lssFirst", 1, 127, 1);
    auto* lss = button("Give node-IDs (LSS)", "lssButton");
    f->addRow("Without node-ID", row({new QLabel("from node-ID"), first_, lss}));
    connect(lss, &QPushButton::clicked, this, [this] {
      run([this] { return w_.builder().lss(iface_->text().toStdString(), first_->value()); });
    });
    found_ = new QListWidget;
    found_->setObjectName("foundDevices");
    f->addRow("Found", found_);
    connect(b, &QPushButton::clicked, this, [this] {
      run([this] {
        return w_.builder().scan(kind_->currentIndex() == 1, iface_->text().toStdString(), dir_->text().toStdString(),
                                 expect_->text().toStdString());
      });
    });
  }
  void refresh(const State& s) override {
    found_->clear();
    for (const auto& n : s.nodes) found_->addItem(QString::fromStdString(describe(n)));
    for (const auto& n : s.slaves) found_->addItem(QString::fromStdString(describe(n)));
    if (iface_->text().isEmpty()) iface_->setText(QString::fromStdString(s.interface));
    if (dir_->text().isEmpty()) dir_->setText(QString::fromStdString(s.eds_dir));
  }

 private:
  QComboBox* kind_;
  QLineEdit *iface_, *dir_, *expect_;
  QSpinBox* first_;
  QListWidget* found_;
};

// ------------------------------------------------------------ 2 axes

class AxesPage : public StepPage {
 public:
  explicit AxesPage(WizardWindow& w)
      : StepPage(w, 1,
                 "Assign each drive to an axis and joint. Identify moves the axis' drive 0.5 mm at 1 mm/s "
                 "(time-limited, the machine switched off afterwards) so you can see which one it is; it needs a "
                 "running controller (Bring up on page 4 or your own).") {
    auto* f = new QFormLayout(inputs());
    letter_ = new QComboBox;
    letter_->setObjectName("assignLetter");
    letter_->addItems({"X", "Y", "Z", "A", "B", "C", "U", "V", "W"});
    f->addRow("Axis", letter_);
    f->addRow("Drive (node-ID)", node_ = count("nodeId", 1, 127, 1));
    f->addRow("Joint", joint_ = count("jointNumber", 0, 15, 0));
    // A gantry pair: the second drive of the axis (0: none), on the next
    // free joint; "turns the other way" when it is mounted mirrored.
    f->addRow("Gantry second drive (node-ID, 0 none)", gantry_ = count("gantryNode", 0, 127, 0));
    gantry_reverse_ = new QCheckBox("the second drive turns the other way (mounted mirrored)");
    gantry_reverse_->setObjectName("gantryReverse");
    f->addRow("", gantry_reverse_);
    auto* assign = button("Assign", "assignButton");
    auto* identify = button("Identify (jog 0.5 mm)", "identifyButton");
    f->addRow(row({assign, identify}));
    axes_ = new QListWidget;
    axes_->setObjectName("axesList");
    f->addRow("Axes", axes_);
    connect(assign, &QPushButton::clicked, this, [this] {
      run([this] {
        return w_.builder().assign(letter_->currentText().at(0).toLatin1(), node_->value(), joint_->value(),
                                   gantry_->value(), gantry_reverse_->isChecked());
      });
    });
    connect(identify, &QPushButton::clicked, this, [this] {
      run([this] {
        // On a copy of the state: the jog's result is not the axis' direction test.
        const QString scratch = w_.options().state_file + ".identify";
        QFile::remove(scratch);
        if (!QFile::copy(w_.options().state_file, scratch))
          throw std::invalid_argument(("cannot copy the state to " + scratch).toStdString());
        return w_.builder().identify(letter_->currentText().at(0).toLatin1(), scratch.toStdString());
      });
    });
  }
  void refresh(const State& s) override {
    axes_->clear();
    for (const auto& a : s.axes) {
      const ScannedNode* n = s.node(a.node);
      axes_->addItem(QString("%1: joint %2, node %3%4%5%6")
                         .arg(QChar(a.letter))
                         .arg(a.joint)
                         .arg(a.node)
                         .arg(n && !n->name.empty() ? " (" + QString::fromStdString(n->name) + ")" : "")
                         .arg(a.gantry ? QString(", gantry pair: node %1 on joint %2%3")
                                             .arg(a.gantry->node)
                                             .arg(a.gantry->joint)
                                             .arg(a.gantry->reverse ? ", reversed" : "")
                                       : QString())
                         .arg(a.enabled ? "" : ", disabled"));
    }
    joint_->setValue(static_cast<int>(machine_joints(s).size()));
  }

 private:
  QComboBox* letter_;
  QSpinBox *node_, *joint_, *gantry_;
  QCheckBox* gantry_reverse_;
  QListWidget* axes_;
};

// ------------------------------------------------------------ 3 scaling

class ScalingPage : public AxisPage {
 public:
  explicit ScalingPage(WizardWindow& w)
      : AxisPage(w, 2,
                 "Counts per mm = encoder increments per motor revolution x motor revolutions per screw "
                 "revolution / screw lead. Leave counts and gear at 0 to take them from the drive (0x608F, "
                 "0x6091).",
                 false) {
    auto* f = form_;
    f->addRow("Screw lead", lead_ = number("screwLead", 0, 1000, 5, 4, " mm"));
    f->addRow("Encoder counts/rev", counts_ = number("encoderCounts", 0, 1e9, 0, 0, ""));
    f->addRow("Gear motor revs", gm_ = number("gearMotor", 0, 1000, 0, 3, ""));
    f->addRow("Gear load revs", gl_ = number("gearLoad", 0, 1000, 0, 3, ""));
    cpm_ = new QLabel;
    cpm_->setObjectName("countsPerMm");
    f->addRow("Counts per mm", cpm_);
    auto* b = button("Set scaling", "scalingButton");
    f->addRow(b);
    for (auto* s : {lead_, counts_, gm_, gl_})
      connect(s, &QDoubleSpinBox::valueChanged, this, [this] { update_live(); });
    connect(b, &QPushButton::clicked, this, [this] {
      run([this] { return w_.builder().scaling(letter(), lead_->value(), counts_->value(), gm_->value(), gl_->value()); });
    });
  }
  void show_axis(const State&) override { update_live(); }
  // The live figure, as set_scaling would compute it (drive values where
  // the fields are 0).
  void update_live() {
    const State& s = w_.state();
    AxisScaling sc;
    sc.screw_lead = lead_->value();
    sc.encoder_counts = counts_->value();
    sc.gear_motor_revs = gm_->value();
    sc.gear_load_revs = gl_->value();
    QStringList sources;
    QString from;
    if (const Axis* a = axis(s)) {
      const ScannedNode* n = s.node(a->node);
      if (sc.encoder_counts <= 0 && n && n->encoder_increments && n->encoder_motor_revs && *n->encoder_motor_revs > 0) {
        sc.encoder_counts = static_cast<double>(*n->encoder_increments) / *n->encoder_motor_revs;
        sources << "counts/rev from the drive";
      }
      if ((sc.gear_motor_revs <= 0 || sc.gear_load_revs <= 0) && n && n->gear_motor_revs && n->gear_shaft_revs &&
          *n->gear_shaft_revs > 0) {
        sc.gear_motor_revs = *n->gear_motor_revs;
        sc.gear_load_revs = *n->gear_shaft_revs;
        sources << "gear from the drive";
      }
      if (!sources.isEmpty()) from = " (" + sources.join(", ") + ")";
      if (a->scaling.counts_per_mm() > 0)
        from += QString("; the state has %1 counts/mm").arg(a->scaling.counts_per_mm(), 0, 'f', 3);
    }
    if (sc.gear_motor_revs <= 0 || sc.gear_load_revs <= 0) sc.gear_motor_revs = sc.gear_load_revs = 1;
    const double cpm = sc.nominal_counts_per_mm();
    cpm_->setText(cpm > 0 && std::isfinite(cpm) ? QString("<b>%1</b>%2").arg(cpm, 0, 'f', 3).arg(from)
                                                : QString("(needs the lead and the counts)") + from);
  }

 private:
  QDoubleSpinBox *lead_, *counts_, *gm_, *gl_;
  QLabel* cpm_;
};

// ------------------------------------------------------------ 4 direction

class DirectionPage : public AxisPage {
 public:
  explicit DirectionPage(WizardWindow& w)
      : AxisPage(w, 3,
                 "Zero a dial indicator on the table, then HOLD the button: the axis jogs the distance at low "
                 "speed while it is held; releasing it stops the motion and switches the machine off. Enter the "
                 "dial's reading (in the axis' positive direction): REVERSE flips and the scaling is corrected "
                 "when they disagree. The test runs on the running controller; Bring up starts one on the "
                 "configuration of the state.",
                 false) {
    auto* f = form_;
    auto* up = button("Bring up controller", "bringUpButton");
    auto* down = button("Shut down controller", "shutdownButton");
    f->insertRow(0, row({up, down}));
    f->addRow("Distance", distance_ = number("testDistance", -kMaxTestTravel, kMaxTestTravel, 5, 3, " mm"));
    f->addRow("Velocity", velocity_ = number("testVelocity", 0.01, kMaxTestVelocity, 2, 2, " mm/s"));
    hold_ = new HoldToRunButton("HOLD TO RUN");
    hold_->setObjectName("holdToRunButton");
    hold_->setMinimumHeight(48);
    hold_->setStyleSheet("QPushButton { font-weight: bold; } QPushButton:pressed { background: #ffd24d; }");
    f->addRow(hold_);
    dial_ = number("dialValue", -1000, 1000, 0, 4, " mm");
    auto* db = button("Apply dial reading", "dialButton");
    f->addRow("Dial indicator", row({dial_, db}));
    f->addRow("Last test", verdict_ = shown("directionVerdict"));
    connect(up, &QPushButton::clicked, this,
            [this] { run([this] { return w_.builder().bring_up(w_.options().config_dir.toStdString()); }); });
    connect(down, &QPushButton::clicked, this, [this] { run([this] { return w_.builder().shutdown(); }); });
    connect(hold_, &HoldToRunButton::startRequested, this, [this] {
      const bool started =
          run([this] { return w_.builder().direction_test(letter(), distance_->value(), velocity_->value()); },
              [this](const StepResult&) { hold_->protocol().finished(); });
      if (started) hold_->protocol().started();
      else hold_->protocol().finished();  // refused: the next press starts again
    });
    connect(hold_, &HoldToRunButton::interruptRequested, this, [this] { child().interrupt(); });
    connect(db, &QPushButton::clicked, this,
            [this] { run([this] { return w_.builder().dial(letter(), dial_->value()); }); });
  }
  void show_axis(const State& s) override {
    const Axis* a = axis(s);
    if (!a || !a->direction) {
      verdict_->setText("(no test yet)");
      return;
    }
    verdict_->setText(QString::fromStdString(a->direction->verdict) +
                      QString("\n%1 counts/mm%2").arg(a->scaling.counts_per_mm(), 0, 'f', 3).arg(a->scaling.reverse ? ", REVERSE" : ""));
  }

 private:
  QDoubleSpinBox *distance_, *velocity_, *dial_;
  HoldToRunButton* hold_;
  QLabel* verdict_;
};

// ------------------------------------------------------------ 5 limits

QString describe_switch(const char* name, const SwitchFinding& f) {
  if (!f.seen) return QString("%1: not seen (%2)").arg(name, QString::fromStdString(f.pin));
  return QString("%1 at %2 mm%3, active %4 (%5)")
      .arg(name, mm(f.position), f.has_high ? " to " + mm(f.position_high) + " mm" : QString(),
           f.active_high ? "high" : "low", QString::fromStdString(f.pin));
}

class LimitsPage : public AxisPage {
 public:
  explicit LimitsPage(WizardWindow& w)
      : AxisPage(w, 4,
                 "Provisional limits and speeds; then find the limit and home switches (each seen, where, with "
                 "which polarity) and derive the soft limits from them less a margin.",
                 true) {
    min_ = number("minLimit", -1e5, 1e5, -10, 3, " mm");
    max_ = number("maxLimit", -1e5, 1e5, 10, 3, " mm");
    vel_ = number("maxVelocity", 0.001, 1e5, 10, 3, " mm/s");
    acc_ = number("maxAcceleration", 0.001, 1e6, 100, 3, " mm/s2");
    auto* lb = button("Set limits", "limitsButton");
    form_->addRow("Limits, speed", row({min_, max_, vel_, acc_, lb}));
    search_ = number("searchDistance", 0, 1e5, 0, 2, " mm");
    svel_ = number("searchVelocity", 0, 1000, 0, 2, " mm/s");
    auto* sb = button("Find switches", "switchesButton");
    form_->addRow("Switch search (0: default)", row({search_, svel_, sb}));
    margin_ = number("softLimitMargin", 0, 1000, 2, 3, " mm");
    auto* mb = button("Soft limits from switches", "softLimitsButton");
    form_->addRow("Margin", row({margin_, mb}));
    form_->addRow("Switches", switches_ = shown("switchesShown"));
    form_->addRow("State", shown_ = shown("limitsShown"));
    connect(lb, &QPushButton::clicked, this, [this] {
      run([this] { return w_.builder().limits(letter(), min_->value(), max_->value(), vel_->value(), acc_->value()); });
    });
    connect(sb, &QPushButton::clicked, this, [this] {
      run([this] { return w_.builder().switches(letter(), search_->value(), svel_->value(), bring_up()); });
    });
    connect(mb, &QPushButton::clicked, this,
            [this] { run([this] { return w_.builder().soft_limits(letter(), margin_->value()); }); });
  }
  void show_axis(const State& s) override {
    const Axis* a = axis(s);
    if (!a) return;
    shown_->setText(QString("limits %1 .. %2 mm, %3 mm/s, %4 mm/s2")
                        .arg(a->min_limit)
                        .arg(a->max_limit)
                        .arg(a->max_velocity)
                        .arg(a->max_acceleration));
    if (!a->switches) {
      switches_->setText("(no switch search yet)");
      return;
    }
    const AxisSwitches& sw = *a->switches;
    switches_->setText(describe_switch("negative limit", sw.neg_limit) + "\n" +
                       describe_switch("positive limit", sw.pos_limit) + "\n" + describe_switch("home switch", sw.home) +
                       QString("\nsearched %1 mm each way from %2 mm at %3 mm/s").arg(mm(sw.search_mm), mm(sw.start), mm(sw.velocity)));
  }

 private:
  QDoubleSpinBox *min_, *max_, *vel_, *acc_, *search_, *svel_, *margin_;
  QLabel *switches_, *shown_;
};

// ------------------------------------------------------------ 6 homing

class HomingPage : public AxisPage {
 public:
  explicit HomingPage(WizardWindow& w)
      : AxisPage(w, 5,
                 "Choose controller homing (the joint's homing sequence) or one of the drive's CiA 402 methods, "
                 "run it and repeat it: the reference position of each run and their spread are shown.",
                 true) {
    method_ = new QComboBox;
    method_->setObjectName("homingMethod");
    method_->addItem("controller: the joint's homing sequence (HOME_* of the INI)", "controller");
    auto* lb = button("List methods", "methodsButton");
    form_->addRow("Method", row({method_, lb}, true));
    form_->addRow("Repeat", repeat_ = count("homingRepeat", 1, 20, 5));
    auto* hb = button("Home", "homingButton");
    form_->addRow(hb);
    form_->addRow("Result", result_ = shown("homingShown"));
    connect(lb, &QPushButton::clicked, this, [this] {
      run([this] { return w_.builder().homing_methods(); },
          [this](const StepResult& r) {
            if (!r.ok()) return;
            method_->clear();
            for (const auto& m : parse_homing_methods(r.lines))
              method_->addItem(QString::fromStdString(m.description), QString::fromStdString(m.method));
          });
    });
    connect(hb, &QPushButton::clicked, this, [this] {
      run([this] {
        return w_.builder().homing(letter(), method_->currentData().toString().toStdString(), repeat_->value(), bring_up());
      });
    });
  }
  void show_axis(const State& s) override {
    const Axis* a = axis(s);
    if (!a || !a->homing) {
      result_->setText("(not homed yet)");
      return;
    }
    const AxisHoming& h = *a->homing;
    QStringList refs;
    for (double r : h.references) refs << QString::number(r, 'f', 4);
    result_->setText(QString("%1: %2 runs, references %3 mm\nspread %4 um (%5)\nHOME_OFFSET %6 mm, HOME %7 mm")
                         .arg(QString::fromStdString(h.method))
                         .arg(h.references.size())
                         .arg(refs.join(" "))
                         .arg(h.spread * 1000, 0, 'f', 2)
                         .arg(QString::fromStdString(h.measured), mm(h.home_offset), mm(h.home)));
  }

 private:
  QComboBox* method_;
  QSpinBox* repeat_;
  QLabel* result_;
};

// ------------------------------------------------------------ 7 tuning

QChartView* trace_chart(const char* name, const QString& title, const QString& unit) {
  auto* chart = new QChart;
  chart->setTitle(title);
  chart->legend()->hide();
  auto* series = new QLineSeries;
  chart->addSeries(series);
  auto* x = new QValueAxis;
  x->setTitleText("s");
  x->setLabelFormat("%.2f");
  x->setTickCount(5);
  auto* y = new QValueAxis;
  y->setTitleText(unit);
  chart->addAxis(x, Qt::AlignBottom);
  chart->addAxis(y, Qt::AlignLeft);
  series->attachAxis(x);
  series->attachAxis(y);
  auto* v = new QChartView(chart);
  v->setObjectName(name);
  v->setMinimumHeight(260);
  v->setRenderHint(QPainter::Antialiasing);
  return v;
}

void plot(QChartView* v, const std::vector<double>& t, const std::vector<double>& y) {
  auto* s = static_cast<QLineSeries*>(v->chart()->series().at(0));
  QList<QPointF> pts;
  double lo = 0, hi = 0;
  for (std::size_t i = 0; i < t.size() && i < y.size(); ++i) {
    pts.append(QPointF(t[i], y[i]));
    lo = i == 0 ? y[i] : std::min(lo, y[i]);
    hi = i == 0 ? y[i] : std::max(hi, y[i]);
  }
  s->replace(pts);
  const double pad = hi > lo ? (hi - lo) * 0.05 : 1.0;
  v->chart()->axes(Qt::Horizontal).at(0)->setRange(t.empty() ? 0 : t.front(), t.empty() ? 1 : t.back());
  v->chart()->axes(Qt::Vertical).at(0)->setRange(lo - pad, hi + pad);
}

// The step response: command and velocity feedback against time.
QChartView* step_chart() {
  QChartView* v = trace_chart("stepChart", "velocity loop: step", "mm/s");
  auto* fb = new QLineSeries;
  fb->setName("velocity");
  v->chart()->addSeries(fb);
  fb->attachAxis(v->chart()->axes(Qt::Horizontal).at(0));
  fb->attachAxis(v->chart()->axes(Qt::Vertical).at(0));
  v->chart()->series().at(0)->setName("command");
  v->chart()->legend()->show();
  return v;
}

void plot_step(QChartView* v, const std::vector<ResponseSample>& r) {
  std::vector<double> t, cmd, fb;
  for (const ResponseSample& x : r) {
    t.push_back(x.time_s);
    cmd.push_back(x.vel_cmd_mm_s);
    fb.push_back(x.velocity_mm_s);
  }
  plot(v, t, cmd);  // the axes' ranges from the command; the feedback's overshoot widens them
  QList<QPointF> pts;
  double lo = 0, hi = 0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    pts.append(QPointF(t[i], fb[i]));
    lo = std::min({lo, fb[i], cmd[i]});
    hi = std::max({hi, fb[i], cmd[i]});
  }
  static_cast<QLineSeries*>(v->chart()->series().at(1))->replace(pts);
  if (hi > lo) v->chart()->axes(Qt::Vertical).at(0)->setRange(lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo));
}

// The swept sine: gain (dB, left) and phase (degrees, right) over a
// logarithmic frequency axis.
QChartView* bode_chart() {
  auto* chart = new QChart;
  chart->setTitle("velocity loop: swept sine");
  auto* gain = new QLineSeries;
  gain->setName("gain dB");
  auto* phase = new QLineSeries;
  phase->setName("phase deg");
  chart->addSeries(gain);
  chart->addSeries(phase);
  auto* f = new QLogValueAxis;
  f->setTitleText("Hz");
  f->setLabelFormat("%g");
  f->setBase(10);
  auto* db = new QValueAxis;
  db->setTitleText("dB");
  auto* deg = new QValueAxis;
  deg->setTitleText("deg");
  chart->addAxis(f, Qt::AlignBottom);
  chart->addAxis(db, Qt::AlignLeft);
  chart->addAxis(deg, Qt::AlignRight);
  gain->attachAxis(f);
  gain->attachAxis(db);
  phase->attachAxis(f);
  phase->attachAxis(deg);
  auto* v = new QChartView(chart);
  v->setObjectName("bodeChart");
  v->setMinimumHeight(260);
  v->setRenderHint(QPainter::Antialiasing);
  return v;
}

void plot_bode(QChartView* v, const std::vector<FrequencyPoint>& p) {
  QList<QPointF> g, ph;
  double glo = -6, ghi = 3, plo = -180, phi = 0;
  for (const FrequencyPoint& x : p) {
    g.append(QPointF(x.frequency_hz, x.gain_db));
    ph.append(QPointF(x.frequency_hz, x.phase_deg));
    glo = std::min(glo, x.gain_db);
    ghi = std::max(ghi, x.gain_db);
    plo = std::min(plo, x.phase_deg);
    phi = std::max(phi, x.phase_deg);
  }
  static_cast<QLineSeries*>(v->chart()->series().at(0))->replace(g);
  static_cast<QLineSeries*>(v->chart()->series().at(1))->replace(ph);
  v->chart()->axes(Qt::Horizontal).at(0)->setRange(p.empty() ? 1 : p.front().frequency_hz, p.empty() ? 100 : p.back().frequency_hz);
  v->chart()->axes(Qt::Vertical).at(0)->setRange(glo - 1, ghi + 1);
  v->chart()->axes(Qt::Vertical).at(1)->setRange(plo - 10, phi + 10);
}

QString response_text(const AxisResponse& r) {
  if (!r.skipped.empty()) return "not measured: " + QString::fromStdString(r.skipped);
  QString t = QString("0x60F9 velocity gain %1, integration time %2").arg(r.gains.velocity_gain).arg(r.gains.velocity_integral);
  if (r.gains.position_gain) t += QString(", 0x60FB position gain %1").arg(*r.gains.position_gain);
  if (r.step)
    t += QString("\nstep +-%1 mm/s: rise %2 ms, overshoot %3 %, settling %4")
             .arg(r.step->amplitude_mm_s)
             .arg(r.step->rise_time_s * 1000, 0, 'f', 1)
             .arg(r.step->overshoot_pct, 0, 'f', 1)
             .arg(r.step->settling_time_s < 0 ? QString("not within the step")
                                               : QString("%1 ms").arg(r.step->settling_time_s * 1000, 0, 'f', 1));
  if (r.chirp)
    t += QString("\nswept sine: -3 dB bandwidth %1%2 Hz (%3 frequencies)")
             .arg(r.chirp->bandwidth_above ? "above " : "")
             .arg(r.chirp->bandwidth_hz, 0, 'f', 1)
             .arg(r.chirp->points.size());
  return t;
}

class TuningPage : public AxisPage {
 public:
  explicit TuningPage(WizardWindow& w)
      : AxisPage(w, 6,
                 "Move tests at rising speed and acceleration, recording following error, torque and velocity; "
                 "the recommended MAX_VELOCITY, MAX_ACCELERATION, MAX_JERK and FERROR/MIN_FERROR keep the stated "
                 "margin. Pick a recording to plot it. Accept gives the axis the recommended speeds for the steps "
                 "after this one; Write puts all the recommendations into the configuration.",
                 true) {
    maxv_ = number("tuneMaxVelocity", 0, 1e5, 0, 2, " mm/s");
    maxa_ = number("tuneMaxAcceleration", 0, 1e6, 0, 1, " mm/s2");
    margin_ = number("tuneMargin", 0, 99, 20, 1, " %");
    steps_ = count("tuneSteps", 0, 20, 0);
    steps_->setSuffix(" tests");
    auto* tb = button("Tune", "tuneButton");
    form_->addRow("Test up to, margin, tests per series (0: default)", row({maxv_, maxa_, margin_, steps_, tb}));
    recommended_ = shown("tuneRecommendation");
    auto* ab = button("Accept", "acceptTuneButton");
    form_->addRow("Recommended", row({recommended_, ab}, true));
    form_->addRow("Accepted", accepted_ = shown("tuneAccepted"));
    recordings_ = new QComboBox;
    recordings_->setObjectName("tuneRecordings");
    form_->addRow("Recording", recordings_);
    trace_error_ = new QLabel;
    trace_error_->setObjectName("traceError");
    trace_error_->setStyleSheet("color: #c00000");
    form_->addRow(trace_error_);
    auto* charts = new QHBoxLayout;
    charts->addWidget(ferror_ = trace_chart("ferrorChart", "following error", "mm"));
    charts->addWidget(torque_ = trace_chart("torqueChart", "torque", "%"));
    charts->addWidget(velocity_ = trace_chart("velocityChart", "velocity", "mm/s"));
    column_->addLayout(charts, 1);
    // The drive's velocity loop (step and swept sine), where the drive
    // exposes its gains (0x60F9).
    response_gain_ = count("responseGain", 0, 2'000'000'000, 0);
    response_gain_->setSpecialValueText("as the drive has it");
    auto* rb = button("Measure response", "responseButton");
    form_->addRow("Velocity loop: gain 0x60F9:1 to write", row({response_gain_, rb}));
    form_->addRow("Loop response", response_ = shown("responseResult"));
    auto* rcharts = new QHBoxLayout;
    rcharts->addWidget(step_ = step_chart());
    rcharts->addWidget(bode_ = bode_chart());
    column_->addLayout(rcharts, 1);
    connect(rb, &QPushButton::clicked, this, [this] {
      run([this] {
        return w_.builder().response(letter(), response_gain_->value(), response_dir().toStdString(),
                                     w_.options().config_dir.toStdString());
      });
    });
    connect(tb, &QPushButton::clicked, this, [this] {
      run([this] {
        return w_.builder().tune(letter(), maxv_->value(), maxa_->value(), margin_->value(), record_dir().toStdString(),
                                 steps_->value(), bring_up());
      });
    });
    connect(ab, &QPushButton::clicked, this, [this] {
      run([this] {
        const Axis* a = axis(w_.state());
        if (!a) throw std::invalid_argument(std::string("axis ") + letter() + ": not assigned");
        return w_.builder().accept_tuning(*a);
      });
    });
    connect(recordings_, &QComboBox::currentIndexChanged, this, [this] { show_recording(); });
  }
  QString record_dir() const { return w_.options().config_dir + "/tune-" + QString(QChar(letter())); }
  QString response_dir() const { return w_.options().config_dir + "/response-" + QString(QChar(letter())); }
  void show_response(const Axis* a) {
    std::vector<ResponseSample> step;
    std::vector<FrequencyPoint> points;
    response_->setText("(not measured yet)");
    if (a && a->response) {
      QString text = response_text(*a->response);
      if (a->response->step) {
        try {
          step = load_response_csv(a->response->step->csv);
        } catch (const std::exception& e) {
          text += "\n" + QString::fromStdString(e.what());
        }
      }
      if (a->response->chirp) points = a->response->chirp->points;
      response_->setText(text);
    }
    plot_step(step_, step);
    plot_bode(bode_, points);
  }
  void show_axis(const State& s) override {
    const Axis* a = axis(s);
    show_response(a);
    if (a && a->tuning) {
      const AxisTuning& t = *a->tuning;
      recommended_->setText(QString("MAX_VELOCITY %1 mm/s, MAX_ACCELERATION %2 mm/s2, MAX_JERK %3 mm/s3, FERROR %4 mm, "
                                    "MIN_FERROR %5 mm (margin %6 %, %7 tests)\nvelocity: %8\nacceleration: %9")
                                .arg(t.max_velocity)
                                .arg(t.max_acceleration)
                                .arg(t.max_jerk)
                                .arg(t.ferror)
                                .arg(t.min_ferror)
                                .arg(t.margin_pct)
                                .arg(t.tests.size())
                                .arg(QString::fromStdString(t.velocity_limit), QString::fromStdString(t.acceleration_limit)));
      const bool accepted = a->max_velocity == t.max_velocity && a->max_acceleration == t.max_acceleration;
      accepted_->setText(accepted ? QString("yes: the axis runs at %1 mm/s, %2 mm/s2").arg(a->max_velocity).arg(a->max_acceleration)
                                  : QString("no: the axis runs at %1 mm/s, %2 mm/s2 (Write uses the recommendations)")
                                        .arg(a->max_velocity)
                                        .arg(a->max_acceleration));
    } else {
      recommended_->setText("(not tuned yet)");
      accepted_->clear();
    }
    list_recordings();
  }
  void list_recordings() {
    const QString keep = recordings_->currentText();
    recordings_->clear();
    for (const QString& f : QDir(record_dir()).entryList({"*.csv"}, QDir::Files, QDir::Name))
      recordings_->addItem(f, record_dir() + "/" + f);
    const int i = recordings_->findText(keep);
    if (i >= 0) recordings_->setCurrentIndex(i);
    show_recording();
  }
  void show_recording() {
    trace_error_->clear();
    const QString file = recordings_->currentData().toString();
    TuneTrace t;
    if (!file.isEmpty()) {
      try {
        t = load_tune_csv(file.toStdString());
      } catch (const std::exception& e) {
        trace_error_->setText(e.what());
      }
    }
    plot(ferror_, t.time_s, t.ferror_mm);
    plot(torque_, t.time_s, t.torque_pct);
    plot(velocity_, t.time_s, t.velocity_mm_s);
  }

 private:
  QComboBox* recordings_;
  QDoubleSpinBox *maxv_, *maxa_, *margin_;
  QSpinBox* steps_;
  QLabel *recommended_, *accepted_, *trace_error_;
  QChartView *ferror_, *torque_, *velocity_;
  QSpinBox* response_gain_;
  QLabel* response_;
  QChartView *step_, *bode_;
};

// ------------------------------------------------------------ 8 compensation

QString figures(const CompFigures& f) {
  return QString("A %1 um (up %2, down %3), E %4 um, R %5 um, B %6 um, M %7 um")
      .arg(f.A, 0, 'f', 2)
      .arg(f.A_up, 0, 'f', 2)
      .arg(f.A_down, 0, 'f', 2)
      .arg(f.E, 0, 'f', 2)
      .arg(f.R, 0, 'f', 2)
      .arg(f.B, 0, 'f', 2)
      .arg(f.M, 0, 'f', 2);
}

class CompensationPage : public AxisPage {
 public:
  explicit CompensationPage(WizardWindow& w)
      : AxisPage(w, 7,
                 "Generate and run the ISO 230-2 measurement cycle (the readings from a laser's HAL pin, a "
                 "camera reading a glass scale, or entered afterwards by hand or from a laser file, CSV), fit the "
                 "compensation and compare the "
                 "figures before and after; Install puts the tables into the state for Write.",
                 true) {
    program_ = line("compProgramFile", "", "cycle.ngc");
    auto* pb = button("Generate cycle", "compProgramButton");
    auto* rb = button("Run cycle", "compRunButton");
    form_->addRow("Cycle", row({program_, pb, rb}, true));
    cmin_ = number("compMin", -1e5, 1e5, 0, 3, " mm");
    cmax_ = number("compMax", -1e5, 1e5, 0, 3, " mm");
    targets_ = count("compTargets", 0, 99, 0);
    targets_->setSuffix(" targets");
    runs_ = count("compRuns", 0, 20, 0);
    runs_->setSuffix(" runs");
    dwell_ = number("compDwell", 0, 60, 0, 2, " s");
    feed_ = number("compFeed", 0, 1e5, 0, 0, " mm/min");
    form_->addRow("Cycle options (0: default)", row({cmin_, cmax_, targets_, runs_, dwell_, feed_}));
    // Where the readings at the stops come from when the cycle runs.
    source_ = new QComboBox;
    source_->setObjectName("compSource");
    source_->addItems({"laser (HAL pin; or its CSV file below, read after the run)", "camera on a glass scale"});
    form_->addRow("Readings from", source_);
    form_->addRow("Laser HAL pin", laser_pin_ = line("compLaserPin", "", "e.g. laser.0.position (mm), read at each stop"));
    camera_ = line("compCamera", "", "/dev/video0, or exec:COMMAND (a program that takes one picture)");
    pitch_ = number("compScalePitch", 0, 10, 0.1, 4, " mm");
    um_per_px_ = number("compUmPerPx", 0, 100, 2.5, 3, " um/px");
    form_->addRow("Camera, scale pitch, pixel scale", row({camera_, pitch_, um_per_px_}, true));
    values_ = new QPlainTextEdit;
    values_->setObjectName("compValues");
    values_->setPlaceholderText("measured deviations (um), one per stop in the cycle's order, one per line or separated by commas");
    values_->setMaximumHeight(70);
    form_->addRow("Measurements", values_);
    csv_ = line("compCsv", "", "laser file (CSV)");
    auto* ib = button("Import...", "compImportButton");
    auto* mb = button("Take measurements", "compMeasurementsButton");
    form_->addRow("or a file", row({csv_, ib, mb}, true));
    install_ = new QCheckBox("install the tables");
    install_->setObjectName("compInstall");
    auto* fb = button("Fit", "compFitButton");
    form_->addRow(row({install_, fb}));
    form_->addRow("Before / after", figures_ = shown("compFigures"));
    connect(pb, &QPushButton::clicked, this, [this] {
      run([this] {
        QString out = program_->text().trimmed();
        if (out.isEmpty()) out = w_.options().config_dir + "/comp-" + QString(QChar(letter())) + ".ngc";
        return w_.builder().comp_program(letter(), out.toStdString(),
                                         {cmin_->value(), cmax_->value(), targets_->value(), runs_->value(),
                                          dwell_->value(), feed_->value()});
      });
    });
    connect(rb, &QPushButton::clicked, this, [this] {
      run([this] {
        if (source_->currentIndex() == 1)
          return w_.builder().comp_run_camera(letter(), camera_->text().toStdString(), pitch_->value(),
                                              um_per_px_->value(), bring_up());
        return w_.builder().comp_run(letter(), csv_->text().toStdString(), laser_pin_->text().toStdString(), bring_up());
      });
    });
    connect(ib, &QPushButton::clicked, this, [this] {
      const QString f = QFileDialog::getOpenFileName(this, "Laser measurement file", QString(), "CSV (*.csv);;All (*)");
      if (!f.isEmpty()) csv_->setText(f);
    });
    connect(mb, &QPushButton::clicked, this, [this] {
      run([this] {
        return w_.builder().comp_measurements(letter(), csv_->text().toStdString(), values_->toPlainText().toStdString());
      });
    });
    connect(fb, &QPushButton::clicked, this,
            [this] { run([this] { return w_.builder().comp_fit(letter(), install_->isChecked()); }); });
  }
  // What the state holds: the cycle, the measurement, the fit (before /
  // predicted with the table), whether Write installs it.
  void show_axis(const State& s) override {
    const Axis* a = axis(s);
    if (!a || !a->compensation) {
      figures_->setText("(no cycle yet)");
      return;
    }
    const AxisCompensation& c = *a->compensation;
    QString t = QString("cycle %1 .. %2 mm, %3 runs each way, %4 points measured")
                    .arg(mm(c.x_min), mm(c.x_max))
                    .arg(c.runs)
                    .arg(c.points.size());
    if (c.measured) t += "\nmeasured (" + QString::fromStdString(c.source) + "): " + figures(*c.measured);
    if (c.fitted) {
      t += "\nbefore:    " + figures(c.before) + "\npredicted: " + figures(c.predicted);
      t += QString("\nfit: A %1 um before, %2 um predicted with the table (%3 entries)")
               .arg(c.before.A, 0, 'f', 2)
               .arg(c.predicted.A, 0, 'f', 2)
               .arg(c.nominal.size());
    }
    if (c.checked) t += "\nchecked on the compensated machine: " + figures(*c.checked);
    t += c.install ? "\ninstalled: Write puts the table into the configuration" : "\nnot installed";
    figures_->setText(t);
  }

 private:
  QLineEdit *program_, *csv_, *laser_pin_, *camera_;
  QComboBox* source_;
  QDoubleSpinBox *cmin_, *cmax_, *dwell_, *feed_, *pitch_, *um_per_px_;
  QSpinBox *targets_, *runs_;
  QPlainTextEdit* values_;
  QCheckBox* install_;
  QLabel* figures_;
};

// ------------------------------------------------------------ 9 write

class WritePage : public StepPage {
 public:
  explicit WritePage(WizardWindow& w)
      : StepPage(w, 8,
                 "Show the difference between the configuration of the state and the files in the folder; "
                 "Write writes them (old ones kept as .bak, checked with cncd --check --strict) after you "
                 "confirm. Backup uploads the drives' parameters (into drive-backup beside the state file); Write copies the "
                 "last backup into the configuration. Then start the controller on the written configuration and run "
                 "the check program.") {
    auto* v = new QVBoxLayout(inputs());
    auto* f = new QFormLayout;
    v->addLayout(f);
    f->addRow("Folder", dir_ = line("configDir", w.options().config_dir));
    f->addRow("Name", name_ = line("configName", "machine"));
    auto* db = button("Show difference", "diffButton");
    auto* wb = button("Write...", "writeButton");
    auto* bb = button("Backup drive parameters", "backupButton");
    f->addRow(row({db, wb, bb}));
    check_ = button("Start the controller on it and run the check program", "checkButton");
    f->addRow(check_);
    f->addRow("Check", checked_ = shown("checkResult"));
    checked_->setText("(not run yet)");
    diff_ = new QTextEdit;
    diff_->setObjectName("diffView");
    diff_->setReadOnly(true);
    diff_->setMinimumHeight(200);
    v->addWidget(diff_);
    connect(db, &QPushButton::clicked, this, [this] {
      run([this] { return w_.builder().write(dir_->text().toStdString(), name_->text().toStdString(), false); },
          [this](const StepResult& r) { show_diff(r); });
    });
    connect(wb, &QPushButton::clicked, this, [this] {
      if (QMessageBox::question(this, "Write the configuration",
                                "Write the configuration to " + dir_->text() + "? Changed files are kept as .bak.") !=
              QMessageBox::Yes)
        return;
      run([this] { return w_.builder().write(dir_->text().toStdString(), name_->text().toStdString(), true); });
    });
    // Beside the state; write copies the last backup into the configuration.
    connect(bb, &QPushButton::clicked, this, [this] {
      run([this] {
        return w_.builder().backup((QFileInfo(w_.options().state_file).absolutePath() + "/drive-backup").toStdString());
      });
    });
    connect(check_, &QPushButton::clicked, this, [this] {
      run([this] { return w_.builder().check(); },
          [this](const StepResult& r) {
            QStringList l;
            for (const auto& s : r.lines) l << QString::fromStdString(s);
            checked_->setText((r.ok() ? "passed\n" : QString::fromStdString(r.summary()) + "\n") + l.join("\n"));
          });
    });
  }
  // The check runs on the written configuration: after a write.
  void refresh(const State&) override { check_->setEnabled(w_.done()[static_cast<std::size_t>(step())]); }
  void show_diff(const StepResult& r) {
    QString html = "<pre style='font-size: 9pt'>";
    for (const auto& s : r.lines) {
      const QString l = QString::fromStdString(s).toHtmlEscaped();
      if (l.startsWith('+') && !l.startsWith("+++")) html += "<span style='color:#1a7f1a'>" + l + "</span>\n";
      else if (l.startsWith('-') && !l.startsWith("---")) html += "<span style='color:#c00000'>" + l + "</span>\n";
      else html += l + "\n";
    }
    diff_->setHtml(html + "</pre>");
  }
 private:
  QLineEdit *dir_, *name_;
  QPushButton* check_;
  QLabel* checked_;
  QTextEdit* diff_;
};

}  // namespace

StepPage* make_page(WizardWindow& w, int step) {
  switch (step) {
    case 0: return new BusPage(w);
    case 1: return new AxesPage(w);
    case 2: return new ScalingPage(w);
    case 3: return new DirectionPage(w);
    case 4: return new LimitsPage(w);
    case 5: return new HomingPage(w);
    case 6: return new TuningPage(w);
    case 7: return new CompensationPage(w);
    default: return new WritePage(w);
  }
}

}  // namespace cnc::commission::wizard
