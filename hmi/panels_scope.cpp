// The Scope page: the controller's HAL scope driven through the screen's
// halcmd channel, the capture plotted and exported.
#include <QCheckBox>
#include <QComboBox>
#include <QFileDialog>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QLabel>
#include <QLineEdit>
#include <QPushButton>
#include <QSpinBox>
#include <QVBoxLayout>
#include <QtCharts/QChart>
#include <QtCharts/QChartView>
#include <QtCharts/QLineSeries>
#include <QtCharts/QValueAxis>
#include <algorithm>
#include <cmath>

#include "core/util/atomic_file.hpp"
#include "hmi/hal_channel.hpp"
#include "hmi/panels.hpp"

namespace cnc::hmi {

namespace {
QComboBox* narrow_combo(QWidget* parent) {
  auto* c = new QComboBox(parent);
  c->setSizeAdjustPolicy(QComboBox::AdjustToMinimumContentsLengthWithIcon);
  c->setMinimumContentsLength(8);
  return c;
}
enum Tag { kStop = ScopePage::kTagFirst, kSetup, kArm, kState, kCsv, kStopOnly };
}

ScopePage::ScopePage(Screen& s, HalChannel* hal, QWidget* parent) : QWidget(parent), s_(s), hal_(hal) {
  setObjectName("scopePage");
  auto* v = new QVBoxLayout(this);
  v->setContentsMargins(2, 2, 2, 2);
  auto* top = new QHBoxLayout();
  v->addLayout(top);
  auto* left = new QFormLayout();
  auto* right = new QFormLayout();
  top->addLayout(left, 3);
  top->addLayout(right, 2);
  pins_ = new QLineEdit("joint.0.pos-cmd,joint.0.pos-fb,joint.0.f-error", this);
  pins_->setObjectName("scopePins");
  pins_->setMinimumWidth(120);
  pins_->setToolTip("HAL pins to record, separated by commas (up to 16 with the trigger)");
  left->addRow("Pins", pins_);
  trigger_ = new QLineEdit(this);
  trigger_->setObjectName("scopeTrigger");
  trigger_->setPlaceholderText("none: start at once");
  left->addRow("Trigger pin", trigger_);
  auto* trow = new QHBoxLayout();
  edge_ = narrow_combo(this);
  edge_->setObjectName("scopeEdge");
  for (auto e : {scope::Edge::Rising, scope::Edge::Falling, scope::Edge::Level}) {
    edge_->addItem(scope::to_string(e), static_cast<int>(e));
  }
  level_ = new QLineEdit("0.5", this);
  level_->setObjectName("scopeLevel");
  trow->addWidget(edge_);
  trow->addWidget(new QLabel("level", this));
  trow->addWidget(level_);
  left->addRow("Edge", trow);
  pre_ = new QSpinBox(this);
  pre_->setObjectName("scopePre");
  pre_->setRange(0, 100);
  pre_->setValue(10);
  pre_->setSuffix(" %");
  right->addRow("Pre-trigger", pre_);
  samples_ = new QSpinBox(this);
  samples_->setObjectName("scopeSamples");
  samples_->setRange(0, 1000000);
  samples_->setValue(0);
  samples_->setSpecialValueText("buffer size");
  samples_->setToolTip("servo cycles to record; 0: the scope buffer's size (loadrt scope samples=N)");
  right->addRow("Samples", samples_);
  mode_ = narrow_combo(this);
  mode_->setObjectName("scopeMode");
  mode_->addItem("single: one capture", static_cast<int>(scope::Mode::Single));
  mode_->addItem("normal: every trigger", static_cast<int>(scope::Mode::Normal));
  mode_->addItem("auto: forced without trigger", static_cast<int>(scope::Mode::Auto));
  right->addRow("Mode", mode_);
  normalise_ = new QCheckBox("own scale per pin", this);
  normalise_->setObjectName("scopeNormalise");
  normalise_->setChecked(true);
  normalise_->setToolTip("draw every pin from its minimum (0) to its maximum (1), its range in the legend: a following "
                         "error beside a position stays visible");

  auto* buttons = new QHBoxLayout();
  run_ = ui::button("Run", "scopeRun", this);
  stop_ = ui::button("Stop", "scopeStop", this);
  export_ = ui::button("Export CSV…", "scopeExport", this);
  buttons->addWidget(run_);
  buttons->addWidget(stop_);
  buttons->addWidget(export_);
  buttons->addWidget(normalise_);
  buttons->addStretch(1);
  state_ = new QLabel(hal_ ? "Scope idle" : "No HAL channel to the controller: the scope is not available", this);
  state_->setObjectName("scopeState");
  state_->setWordWrap(true);
  state_->setMinimumWidth(80);
  v->addLayout(buttons);
  v->addWidget(state_);
  auto* chart = new QChart();
  chart->legend()->setAlignment(Qt::AlignBottom);
  chart->setMargins(QMargins(2, 2, 2, 2));
  view_ = new QChartView(chart, this);
  view_->setObjectName("scopeChart");
  view_->setRenderHint(QPainter::Antialiasing, false);
  view_->setMinimumHeight(200);
  v->addWidget(view_, 1);
  connect(run_, &QPushButton::clicked, this, [this]() { run(); });
  connect(normalise_, &QCheckBox::toggled, this, [this](bool) { plot(); });
  connect(stop_, &QPushButton::clicked, this, [this]() { stop(); });
  connect(export_, &QPushButton::clicked, this, [this]() {
    const QString path = QFileDialog::getSaveFileName(this, "Export the capture", "scope.csv", "CSV (*.csv)");
    if (!path.isEmpty()) export_csv(path);
  });
  if (hal_) connect(hal_, &HalChannel::replied, this, &ScopePage::replied);
  export_->setEnabled(false);
  run_->setEnabled(hal_ != nullptr);
  stop_->setEnabled(false);
}

ScopePage::~ScopePage() = default;

bool ScopePage::run() {
  if (!hal_) return false;
  scope::Settings st;
  st.pins = scope::split_pins(pins_->text().toStdString());
  st.trigger = trigger_->text().trimmed().toStdString();
  st.edge = static_cast<scope::Edge>(edge_->currentData().toInt());
  std::string why;
  const auto level = parse_operator_number(level_->text().toStdString(), &why);
  if (!level) {
    ui::set_text(state_, QString::fromStdString("Level: " + why));
    return false;
  }
  st.level = *level;
  st.pre_percent = pre_->value();
  st.samples = samples_->value();
  st.mode = static_cast<scope::Mode>(mode_->currentData().toInt());
  std::string line;
  try {
    line = scope::setup_line(st);
  } catch (const std::invalid_argument& e) {
    ui::set_text(state_, QString::fromStdString(std::string("Not started: ") + e.what()));
    return false;
  }
  normal_mode_ = st.mode == scope::Mode::Normal;
  hal_->request("scope stop", kStop);
  hal_->request(QString::fromStdString(line), kSetup);
  hal_->request("scope arm", kArm);
  capturing_ = true;
  state_pending_ = false;
  run_->setEnabled(false);
  stop_->setEnabled(true);
  ui::set_text(state_, "Armed…");
  s_.log(LogLevel::Info, "scope: " + line, "scope");
  return true;
}

void ScopePage::stop() {
  if (!hal_) return;
  hal_->request("scope stop", kStopOnly);
  capturing_ = false;
  run_->setEnabled(true);
  stop_->setEnabled(false);
  ui::set_text(state_, "Stopped");
}

void ScopePage::refresh() {
  if (!capturing_ || state_pending_ || !hal_) return;
  state_pending_ = true;
  hal_->request("scope state", kState);
}

void ScopePage::replied(int tag, const QString& line, bool ok, const QString& text) {
  if (tag < kTagFirst || tag > kTagLast) return;
  if (!ok) {
    if (tag == kStop || tag == kStopOnly) return;  // nothing to stop (no capture yet)
    capturing_ = false;
    state_pending_ = false;
    run_->setEnabled(true);
    stop_->setEnabled(false);
    ui::set_text(state_, "Scope: " + text.trimmed());
    s_.log(LogLevel::Error, "scope: " + line.toStdString() + ": " + text.trimmed().toStdString(), "scope");
    return;
  }
  if (tag == kState) {
    state_pending_ = false;
    if (!capturing_) return;
    scope::State st;
    try {
      st = scope::parse_state(text.toStdString());
    } catch (const std::invalid_argument& e) {
      ui::set_text(state_, e.what());
      return;
    }
    if (st.done()) {
      state_pending_ = true;  // no state polls until the data is in
      hal_->request("scope csv", kCsv);
      return;
    }
    ui::set_text(state_, QString("Scope %1: %2 samples, %3 before the trigger")
                             .arg(QString::fromStdString(st.name))
                             .arg(st.samples)
                             .arg(st.pre));
    return;
  }
  if (tag == kCsv) {
    state_pending_ = false;
    try {
      capture_ = std::make_unique<scope::Capture>(scope::parse_csv(text.toStdString()));
    } catch (const std::invalid_argument& e) {
      ui::set_text(state_, e.what());
      capturing_ = false;
      return;
    }
    ++captures_;
    plot();
    export_->setEnabled(true);
    // Normal mode: reading the capture re-armed the scope for the next trigger.
    capturing_ = normal_mode_;
    run_->setEnabled(!capturing_);
    stop_->setEnabled(capturing_);
    const double span = capture_->time.empty() ? 0 : capture_->time.back() - capture_->time.front();
    ui::set_text(state_, QString("Capture %1: %2 samples over %3 s%4")
                             .arg(captures_)
                             .arg(capture_->time.size())
                             .arg(span, 0, 'f', 3)
                             .arg(capturing_ ? "; waiting for the next trigger" : ""));
  }
}

void ScopePage::plot() {
  QChart* chart = view_->chart();
  chart->removeAllSeries();
  for (QAbstractAxis* a : chart->axes()) {
    chart->removeAxis(a);
    delete a;
  }
  if (!capture_ || capture_->time.empty()) return;
  auto* x = new QValueAxis();
  x->setTitleText("time from the trigger (s)");
  x->setRange(capture_->time.front(), capture_->time.back());
  auto* y = new QValueAxis();
  chart->addAxis(x, Qt::AlignBottom);
  chart->addAxis(y, Qt::AlignLeft);
  const bool normalise = normalise_->isChecked();
  double lo = 0, hi = 0;
  bool first = true;
  // At most about 2000 points per line on the screen; the CSV keeps all.
  const std::size_t n = capture_->time.size();
  const std::size_t step = std::max<std::size_t>(1, n / 2000);
  for (std::size_t c = 0; c < capture_->columns.size(); ++c) {
    const auto& col = capture_->columns[c];
    const auto [mn, mx] = std::minmax_element(col.begin(), col.end());
    const double cmin = *mn, cmax = *mx;
    auto* series = new QLineSeries();
    QString name = QString::fromStdString(capture_->names[c]);
    if (normalise) name += QString(" (%1 … %2)").arg(cmin, 0, 'g', 5).arg(cmax, 0, 'g', 5);
    series->setName(name);
    QList<QPointF> pts;
    pts.reserve(static_cast<qsizetype>(n / step + 1));
    for (std::size_t i = 0; i < n; i += step) {
      double val = col[i];
      if (normalise) val = cmax > cmin ? (val - cmin) / (cmax - cmin) : 0.5;
      pts.append(QPointF(capture_->time[i], val));
      if (first || val < lo) lo = val;
      if (first || val > hi) hi = val;
      first = false;
    }
    series->replace(pts);
    chart->addSeries(series);
    series->attachAxis(x);
    series->attachAxis(y);
  }
  y->setTitleText(normalise ? "each pin: 0 = its minimum, 1 = its maximum" : "value");
  const double pad = hi > lo ? (hi - lo) * 0.05 : std::max(1e-6, std::fabs(hi) * 0.05 + 1e-6);
  y->setRange(lo - pad, hi + pad);
}

bool ScopePage::export_csv(const QString& path) {
  if (!capture_) {
    ui::set_text(state_, "Nothing to export: no capture yet");
    return false;
  }
  try {
    write_file_atomically(path.toStdString(), capture_->csv);
  } catch (const std::exception& e) {
    ui::set_text(state_, QString("Export failed: ") + e.what());
    s_.log(LogLevel::Error, std::string("scope export: ") + e.what(), "scope");
    return false;
  }
  ui::set_text(state_, "Exported to " + path);
  return true;
}

}  // namespace cnc::hmi
