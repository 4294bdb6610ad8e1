// Tool table, work offsets, alarms and drives pages.
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QLineEdit>
#include <QListWidget>
#include <QPlainTextEdit>
#include <QPushButton>
#include <QScroller>
#include <QSpinBox>
#include <QTableWidget>
#include <QVBoxLayout>
#include <QtCharts/QChart>
#include <QtCharts/QChartView>
#include <QtCharts/QLineSeries>
#include <QtCharts/QValueAxis>
#include <algorithm>
#include <cmath>

#include "hmi/panels.hpp"
#include "hmi/readouts.hpp"
#include "hmi/trends.hpp"
#include "hmi/positions.hpp"

namespace cnc::hmi {
namespace {

enum Field { kTool = 0, kPocket = 1, kOffset0 = 10, kDiameter = 20, kFront = 21, kBack = 22, kOrientation = 23, kComment = 24 };

QTableWidget* make_table(QWidget* parent, const char* name) {
  auto* t = new QTableWidget(parent);
  t->setObjectName(name);
  t->setFocusPolicy(Qt::ClickFocus);
  t->verticalHeader()->setDefaultSectionSize(ui::kTouch - 6);
  t->verticalHeader()->setVisible(false);
  t->setSelectionBehavior(QAbstractItemView::SelectRows);
  t->setSelectionMode(QAbstractItemView::SingleSelection);
  t->setEditTriggers(QAbstractItemView::DoubleClicked | QAbstractItemView::SelectedClicked | QAbstractItemView::EditKeyPressed);
  QScroller::grabGesture(t->viewport(), QScroller::TouchGesture);
  return t;
}

QTableWidgetItem* item(const QString& text, bool editable, bool bold = false) {
  auto* it = new QTableWidgetItem(text);
  it->setTextAlignment(Qt::AlignRight | Qt::AlignVCenter);
  if (!editable) it->setFlags(it->flags() & ~Qt::ItemIsEditable);
  if (bold) {
    QFont f = it->font();
    f.setBold(true);
    it->setFont(f);
  }
  return it;
}

}  // namespace

// ------------------------------------------------------------ ToolPage

ToolPage::ToolPage(Screen& s, QWidget* parent) : QWidget(parent), s_(s) {
  setObjectName("toolPage");
  auto* v = new QVBoxLayout(this);
  note_ = new QLabel(this);
  note_->setObjectName("toolNote");
  note_->setWordWrap(true);
  v->addWidget(note_);
  table_ = make_table(this, "toolTable");
  columns_ = {kTool, kPocket};
  QStringList heads = {"Tool", "Pocket"};
  if (s_.config.lathe) {
    columns_.insert(columns_.end(), {kOffset0 + 0, kOffset0 + 2, kDiameter, kFront, kBack, kOrientation, kComment});
    heads << "X offset" << "Z offset" << "Diameter" << "Front angle" << "Back angle" << "Orient." << "Comment";
  } else {
    columns_.insert(columns_.end(), {kOffset0 + 2, kDiameter, kComment});
    heads << "Length (Z)" << "Diameter" << "Comment";
  }
  table_->setColumnCount(static_cast<int>(columns_.size()));
  table_->setHorizontalHeaderLabels(heads);
  table_->horizontalHeader()->setStretchLastSection(true);
  v->addWidget(table_, 1);
  auto* row = new QHBoxLayout();
  new_tool_ = new QSpinBox(this);
  new_tool_->setObjectName("newToolNumber");
  new_tool_->setRange(1, 99999);
  new_tool_->setPrefix("T");
  new_pocket_ = new QSpinBox(this);
  new_pocket_->setObjectName("newToolPocket");
  new_pocket_->setRange(1, tooltable::kMaxPocket);
  new_pocket_->setPrefix("P");
  for (auto* sb : {new_tool_, new_pocket_}) {
    sb->setMinimumHeight(ui::kTouch - 8);
    sb->setFocusPolicy(Qt::ClickFocus);
  }
  auto* add = ui::button("Add tool", "toolAdd", this);
  auto* del = ui::button("Delete tool", "toolDelete", this);
  auto* load = ui::button("Reload table", "toolReload", this);
  row->addWidget(new_tool_);
  row->addWidget(new_pocket_);
  row->addWidget(add);
  row->addStretch(1);
  row->addWidget(del);
  row->addWidget(load);
  v->addLayout(row);
  connect(table_, &QTableWidget::cellChanged, this, [this](int r, int c) {
    if (!filling_) cell_edited(r, c);
  });
  connect(add, &QPushButton::clicked, this, [this]() {
    tooltable::Tool t;
    t.number = new_tool_->value();
    t.pocket = new_pocket_->value();
    if (s_.tools.find_tool_anywhere(t.number)) {
      s_.log(LogLevel::Warning, "tool " + std::to_string(t.number) + " is already in the table");
      return;
    }
    s_.send(commands::tool_set(t, true), "add tool " + std::to_string(t.number), [this](const ipc::CommandResult&) { reload_file(); });
  });
  connect(del, &QPushButton::clicked, this, [this]() {
    const int r = table_->currentRow();
    if (r < 0 || !table_->item(r, 0)) {
      s_.log(LogLevel::Warning, "delete tool: select a tool first");
      return;
    }
    const int number = table_->item(r, 0)->text().toInt();
    s_.send(commands::tool_delete(number), "delete tool " + std::to_string(number), [this](const ipc::CommandResult&) { reload_file(); });
  });
  connect(load, &QPushButton::clicked, this, [this]() {
    s_.send(commands::tool_reload(), "reload the tool table", [this](const ipc::CommandResult&) { reload_file(); });
  });
  reload_file();
}

void ToolPage::reload_file() {
  if (s_.config.tool_table.empty()) {
    note_->setText("No [EMCIO]TOOL_TABLE in the INI file.");
    return;
  }
  try {
    s_.tools = tooltable::ToolTable::load(s_.config.tool_table, s_.config.random_toolchanger ? tooltable::ChangerKind::Random
                                                                                             : tooltable::ChangerKind::NonRandom);
    note_->setText(QString("%1 — edits go to the controller, which saves the file. Double-tap a value to change it.")
                       .arg(QString::fromStdString(s_.config.tool_table.string())));
  } catch (const std::exception& e) {
    note_->setText(QString("Cannot read the tool table: %1").arg(e.what()));
    s_.log(LogLevel::Warning, std::string("tool table: ") + e.what());
  }
  fill();
}

void ToolPage::fill() {
  filling_ = true;
  auto tools = s_.tools.tools();
  std::sort(tools.begin(), tools.end(), [](const tooltable::Tool& a, const tooltable::Tool& b) { return a.number < b.number; });
  table_->setRowCount(static_cast<int>(tools.size()));
  const int active = s_.connected ? s_.status.io.tool_in_spindle : 0;
  const int dec = s_.config.dro_decimals(s_.config.machine_inch);
  for (int r = 0; r < static_cast<int>(tools.size()); ++r) {
    const auto& t = tools[static_cast<std::size_t>(r)];
    const bool bold = t.number == active;
    for (int c = 0; c < static_cast<int>(columns_.size()); ++c) {
      const int f = columns_[static_cast<std::size_t>(c)];
      QString text;
      if (f == kTool) text = QString::number(t.number);
      else if (f == kPocket) text = QString::number(t.pocket);
      else if (f >= kOffset0 && f < kOffset0 + kNumAxes) text = s_.number(t.offset[f - kOffset0], dec);
      else if (f == kDiameter) text = s_.number(t.diameter, dec);
      else if (f == kFront) text = s_.number(t.front_angle, 2);
      else if (f == kBack) text = s_.number(t.back_angle, 2);
      else if (f == kOrientation) text = QString::number(t.orientation);
      else if (f == kComment) text = QString::fromStdString(t.comment);
      QTableWidgetItem* it = item(text, f != kTool, bold);
      if (f == kComment) it->setTextAlignment(Qt::AlignLeft | Qt::AlignVCenter);
      if (bold) it->setBackground(QColor(0xd8, 0xec, 0xff));
      table_->setItem(r, c, it);
    }
  }
  table_->resizeColumnsToContents();
  shown_tool_ = active;
  filling_ = false;
}

void ToolPage::cell_edited(int row, int column) {
  const int number = table_->item(row, 0)->text().toInt();
  const auto idx = s_.tools.find_tool_anywhere(number);
  if (!idx) return;
  tooltable::Tool t = s_.tools.at(*idx);
  const int f = columns_[static_cast<std::size_t>(column)];
  const QString text = table_->item(row, column)->text();
  if (f == kComment) {
    t.comment = text.toStdString();
  } else {
    std::string why;
    const auto v = parse_operator_number(text.toStdString(), &why);
    const bool integer = f == kPocket || f == kOrientation;
    if (!v || (integer && std::floor(*v) != *v)) {
      s_.log(LogLevel::Warning, "tool " + std::to_string(number) + ": \"" + text.toStdString() + "\": " +
                                    (v ? "a whole number is needed" : why));
      fill();
      return;
    }
    if (f == kPocket) t.pocket = static_cast<int>(*v);
    else if (f >= kOffset0 && f < kOffset0 + kNumAxes) t.offset[f - kOffset0] = *v;
    else if (f == kDiameter) t.diameter = *v;
    else if (f == kFront) t.front_angle = *v;
    else if (f == kBack) t.back_angle = *v;
    else if (f == kOrientation) t.orientation = static_cast<int>(*v);
  }
  const bool in_spindle = s_.connected && s_.status.io.tool_in_spindle == number;
  s_.send(commands::tool_set(t, f == kPocket), "tool " + std::to_string(number), [this, number, in_spindle](const ipc::CommandResult& r) {
    if (r.state == ipc::CommandState::Done && in_spindle) {
      s_.log(LogLevel::Warning, "tool " + std::to_string(number) +
                                    " is in the spindle: its new offsets apply when G43 is given again (MDI: G43)");
    }
    reload_file();
  });
}

void ToolPage::refresh() {
  const bool editable = s_.is_idle();
  table_->setEditTriggers(editable ? QAbstractItemView::DoubleClicked | QAbstractItemView::SelectedClicked |
                                         QAbstractItemView::EditKeyPressed
                                   : QAbstractItemView::NoEditTriggers);
  if (s_.connected && s_.status.io.tool_in_spindle != shown_tool_) fill();
}

// ------------------------------------------------------------ OffsetsPage

OffsetsPage::OffsetsPage(Screen& s, QWidget* parent) : QWidget(parent), s_(s) {
  setObjectName("offsetsPage");
  auto* v = new QVBoxLayout(this);
  note_ = new QLabel(this);
  note_->setWordWrap(true);
  note_->setObjectName("offsetsNote");
  v->addWidget(note_);
  table_ = make_table(this, "offsetTable");
  QStringList heads;
  for (const auto& a : s_.config.axes) {
    axis_columns_.push_back(a.index);
    heads << QString(a.letter);
  }
  heads << "Rot. XY °";
  table_->setColumnCount(static_cast<int>(axis_columns_.size()) + 1);
  table_->setHorizontalHeaderLabels(heads);
  table_->setRowCount(10);
  QStringList rows;
  for (int i = 1; i <= 9; ++i) rows << ui::qs(work_offset_name(i));
  rows << "G92";
  table_->setVerticalHeaderLabels(rows);
  table_->verticalHeader()->setVisible(true);
  table_->horizontalHeader()->setSectionResizeMode(QHeaderView::Stretch);
  v->addWidget(table_, 1);
  auto* row = new QHBoxLayout();
  auto* clear_row = ui::button("Clear selected", "offsetClear", this);
  auto* clear_g92 = ui::button("Clear G92", "offsetClearG92", this);
  auto* reread = ui::button("Re-read", "offsetReread", this);
  row->addWidget(clear_row);
  row->addWidget(clear_g92);
  row->addStretch(1);
  row->addWidget(reread);
  v->addLayout(row);
  connect(table_, &QTableWidget::cellChanged, this, [this](int r, int c) {
    if (!filling_) cell_edited(r, c);
  });
  connect(clear_row, &QPushButton::clicked, this, [this]() {
    const int r = table_->currentRow();
    if (r < 0) {
      s_.log(LogLevel::Warning, "clear offsets: select a row first");
      return;
    }
    const int index = r == 9 ? 0 : r + 1;
    s_.send(commands::set_work_offset(index, Pose{}, 0), "clear " + work_offset_name(index),
            [this](const ipc::CommandResult&) { reload_file(); });
  });
  connect(clear_g92, &QPushButton::clicked, this, [this]() {
    s_.send(commands::set_work_offset(0, Pose{}, 0), "clear G92", [this](const ipc::CommandResult&) { reload_file(); });
  });
  connect(reread, &QPushButton::clicked, this, [this]() { reload_file(); });
  reload_file();
}

void OffsetsPage::reload_file() { fill(); }

void OffsetsPage::fill() {
  WorkOffsets w;
  if (!s_.config.parameter_file.empty()) w = read_work_offsets(s_.config.parameter_file);
  if (!w.error.empty()) note_->setText(QString("Parameter file: %1").arg(QString::fromStdString(w.error)));
  else note_->setText("Double-tap a value to change it; the controller applies it (G10 L2 / G92) and saves the parameter file.");
  const auto& st = s_.status;
  // The controller's view of the active system and G92 is the newest.
  if (s_.connected && st.task.g5x_index >= 1 && st.task.g5x_index <= 9) {
    w.g5x[st.task.g5x_index - 1] = st.task.g5x_offset;
    w.rotation[st.task.g5x_index - 1] = st.task.rotation_xy;
    w.g92 = st.task.g92_offset;
    w.active = st.task.g5x_index;
  }
  filling_ = true;
  const int dec = s_.config.dro_decimals(s_.connected ? program_inch(st) : s_.config.machine_inch);
  for (int r = 0; r < 10; ++r) {
    const bool g92 = r == 9;
    const bool active = !g92 && r + 1 == w.active;
    for (int c = 0; c < static_cast<int>(axis_columns_.size()); ++c) {
      const int a = axis_columns_[static_cast<std::size_t>(c)];
      const double v = g92 ? w.g92[a] : w.g5x[r][a];
      QTableWidgetItem* it = item(s_.number(v, is_linear_axis(a) ? dec : 3), true, active);
      if (active) it->setBackground(QColor(0xd8, 0xec, 0xff));
      table_->setItem(r, c, it);
    }
    QTableWidgetItem* rot = item(g92 ? QString() : s_.number(w.rotation[r], 3), !g92, active);
    if (active) rot->setBackground(QColor(0xd8, 0xec, 0xff));
    table_->setItem(r, static_cast<int>(axis_columns_.size()), rot);
  }
  shown_active_ = w.active;
  filling_ = false;
}

void OffsetsPage::cell_edited(int row, int column) {
  const int index = row == 9 ? 0 : row + 1;
  Pose values;
  double rotation = 0;
  for (int c = 0; c <= static_cast<int>(axis_columns_.size()); ++c) {
    const QTableWidgetItem* it = table_->item(row, c);
    const std::string text = it ? it->text().toStdString() : "0";
    std::string why;
    const auto v = text.empty() ? std::optional<double>(0.0) : parse_operator_number(text, &why);
    if (!v) {
      s_.log(LogLevel::Warning, work_offset_name(index) + ": \"" + text + "\": " + why);
      fill();
      return;
    }
    if (c < static_cast<int>(axis_columns_.size())) values[axis_columns_[static_cast<std::size_t>(c)]] = *v;
    else rotation = *v;
  }
  (void)column;
  s_.send(commands::set_work_offset(index, values, rotation), "set " + work_offset_name(index),
          [this](const ipc::CommandResult&) { reload_file(); });
}

void OffsetsPage::refresh() {
  const bool editable = s_.is_idle();
  table_->setEditTriggers(editable ? QAbstractItemView::DoubleClicked | QAbstractItemView::SelectedClicked |
                                         QAbstractItemView::EditKeyPressed
                                   : QAbstractItemView::NoEditTriggers);
  if (s_.connected && s_.status.task.g5x_index != shown_active_ && !table_->isPersistentEditorOpen(table_->currentIndex()) && !table_->findChild<QLineEdit*>()) fill();
}

// ------------------------------------------------------------ AlarmsPage

AlarmsPage::AlarmsPage(Screen& s, QWidget* parent) : QWidget(parent), s_(s) {
  setObjectName("alarmsPage");
  auto* v = new QVBoxLayout(this);
  auto* row = new QHBoxLayout();
  row->addWidget(new QLabel("<b>Active alarms</b> (need acknowledging)", this), 1);
  ack_ = ui::button("Acknowledge", "ackButton", this);
  ack_all_ = ui::button("Acknowledge all", "ackAllButton", this);
  row->addWidget(ack_);
  row->addWidget(ack_all_);
  v->addLayout(row);
  list_ = new QListWidget(this);
  list_->setObjectName("alarmList");
  list_->setFocusPolicy(Qt::NoFocus);
  list_->setWordWrap(true);
  list_->setStyleSheet("QListWidget{color:#a00000;font-weight:bold;}");
  QScroller::grabGesture(list_->viewport(), QScroller::TouchGesture);
  v->addWidget(list_, 2);
  v->addWidget(new QLabel("<b>Log</b>", this));
  log_ = new QPlainTextEdit(this);
  log_->setObjectName("logView");
  log_->setReadOnly(true);
  log_->setFocusPolicy(Qt::NoFocus);
  log_->setMaximumBlockCount(5000);
  log_->setLineWrapMode(QPlainTextEdit::WidgetWidth);
  QScroller::grabGesture(log_->viewport(), QScroller::TouchGesture);
  v->addWidget(log_, 3);
  connect(ack_, &QPushButton::clicked, this, [this]() {
    QListWidgetItem* it = list_->currentItem();
    if (!it && list_->count() > 0) it = list_->item(0);
    if (!it) return;
    s_.alarms.acknowledge(it->data(Qt::UserRole).toULongLong(), s_.now_ns ? s_.now_ns() : 0);
    refresh_alarms();
  });
  connect(ack_all_, &QPushButton::clicked, this, [this]() {
    s_.alarms.acknowledge_all(s_.now_ns ? s_.now_ns() : 0);
    refresh_alarms();
  });
  refresh_alarms();
}

void AlarmsPage::refresh_alarms() {
  list_->clear();
  for (const Alarm* a : s_.alarms.active()) {
    auto* it = new QListWidgetItem(QString("%1  [%2]  %3%4")
                                       .arg(QString::fromStdString(AlarmLog::format_time(a->time_ns)),
                                            QString::fromStdString(a->source),
                                            a->count > 1 ? QString("×%1  ").arg(a->count) : QString(),
                                            QString::fromStdString(a->text)));
    it->setData(Qt::UserRole, QVariant::fromValue<qulonglong>(a->id));
    list_->addItem(it);
  }
  ack_->setEnabled(list_->count() > 0);
  ack_all_->setEnabled(list_->count() > 0);
}

void AlarmsPage::append_log(const LogEntry& e) {
  const QString color = e.level == LogLevel::Error     ? "#b00000"
                        : e.level == LogLevel::Warning ? "#a06000"
                        : e.level == LogLevel::Operator ? "#0040a0"
                                                        : "#303030";
  log_->appendHtml(QString("<span style='color:%1'>%2 %3 [%4] %5</span>")
                       .arg(color, QString::fromStdString(AlarmLog::format_time(e.time_ns)), to_string(e.level),
                            QString::fromStdString(e.source).toHtmlEscaped(), QString::fromStdString(e.text).toHtmlEscaped()));
}

// ------------------------------------------------------------ DrivesPage

namespace {
enum DriveColumn { kColJoint, kColDrive, kColStatusword, kColFault, kColFerror, kColTorque, kColVelocity, kDriveColumns };
constexpr int kDriveSlots = kMaxJoints + 1;
}  // namespace

// Three charts (following error, torque, velocity), one line per drive.
class DriveCharts {
 public:
  struct Plot {
    QChart* chart = nullptr;
    QChartView* view = nullptr;
    QValueAxis* x = nullptr;
    QValueAxis* y = nullptr;
    std::array<QLineSeries*, kDriveSlots> series{};
  };
  std::array<Plot, 3> plots;
  std::array<DriveTrends, kDriveSlots> trends;
  std::array<QString, kDriveSlots> names;
  double now_s = 0;
};

DrivesPage::DrivesPage(Screen& s, QWidget* parent) : QWidget(parent), s_(s), charts_(std::make_unique<DriveCharts>()) {
  setObjectName("drivesPage");
  auto* v = new QVBoxLayout(this);
  v->setContentsMargins(2, 2, 2, 2);
  note_ = new QLabel(this);
  note_->setWordWrap(true);
  v->addWidget(note_);
  table_ = make_table(this, "driveTable");
  table_->setEditTriggers(QAbstractItemView::NoEditTriggers);
  table_->setWordWrap(true);
  table_->setHorizontalScrollBarPolicy(Qt::ScrollBarAlwaysOff);
  const QString len = s_.config.machine_inch ? "in" : "mm";
  // Short headers (the columns are narrow at 1024 px), the units in them,
  // the details in their tooltips.
  const QStringList heads = {"Joint", "Drive", "Status-\nword", "Fault", QString("F-error\n(%1)").arg(len), "Torque\n(%)",
                             QString("Velocity\n(%1/s)").arg(len)};
  const QStringList tips = {"joint, axis, homed",
                            "drive name: CiA 402 state, mode of operation (8 CSP, 9 CSV, ...)",
                            "statusword 0x6041 with CiA 402's short names of the bits set (RTSO ready to switch on, SO "
                            "switched on, OE operation enabled, F fault, VE voltage enabled, QS! quick stop active, SOD "
                            "switch on disabled, W warning, RM remote, TR target reached, ILA internal limit active, SPF "
                            "set-point followed, FE following error); the selected drive's in full below the table",
                            "error code 0x603F and its text",
                            QString("following error in %1: motion's now / limit, its highest so far, the drive's own").arg(len),
                            "torque in % of the rated torque",
                            QString("velocity in %1/s (°/s for angular joints, the spindle in rpm)").arg(len)};
  table_->setColumnCount(kDriveColumns);
  table_->setHorizontalHeaderLabels(heads);
  for (int c = 0; c < kDriveColumns; ++c) table_->horizontalHeaderItem(c)->setToolTip(tips[c]);
  QHeaderView* h = table_->horizontalHeader();
  h->setSectionResizeMode(QHeaderView::Stretch);
  h->setSectionResizeMode(kColJoint, QHeaderView::ResizeToContents);
  h->setSectionResizeMode(kColTorque, QHeaderView::ResizeToContents);
  table_->verticalHeader()->setSectionResizeMode(QHeaderView::ResizeToContents);
  v->addWidget(table_, 3);
  detail_ = new QLabel(this);
  detail_->setObjectName("driveStatuswordDetail");
  detail_->setWordWrap(true);
  v->addWidget(detail_);
  connect(table_, &QTableWidget::itemSelectionChanged, this, [this]() { refresh(); });

  // Trends: the last 30 s of every drive.
  legend_ = new QLabel(this);
  legend_->setObjectName("trendLegend");
  legend_->setWordWrap(true);
  v->addWidget(legend_);
  auto* plots = new QHBoxLayout();
  const char* titles[3] = {"Following error", "Torque", "Velocity"};
  const QString units[3] = {len, "% rated", len + "/s (spindle rpm)"};
  const char* names[3] = {"trendFollowingError", "trendTorque", "trendVelocity"};
  for (int i = 0; i < 3; ++i) {
    DriveCharts::Plot& p = charts_->plots[static_cast<std::size_t>(i)];
    p.chart = new QChart();
    p.chart->setTitle(QString("%1 (%2)").arg(titles[i], units[i]));
    p.chart->legend()->hide();  // one legend for the three, above them (legend_)
    p.chart->setMargins(QMargins(0, 0, 0, 0));
    QFont small = p.chart->font();
    small.setPointSizeF(std::max(6.0, small.pointSizeF() * 0.8));
    p.chart->setTitleFont(small);
    p.x = new QValueAxis();
    p.x->setLabelFormat("%.0f s");
    p.x->setTickCount(4);
    p.x->setLabelsFont(small);
    p.y = new QValueAxis();
    p.y->setLabelFormat("%.2g");
    p.y->setTickCount(5);
    p.y->setLabelsFont(small);
    p.chart->addAxis(p.x, Qt::AlignBottom);
    p.chart->addAxis(p.y, Qt::AlignLeft);
    p.view = new QChartView(p.chart, this);
    p.view->setObjectName(names[i]);
    p.view->setRenderHint(QPainter::Antialiasing, false);
    p.view->setMinimumSize(120, 150);  // the page must not widen the window beyond 1024 px
    plots->addWidget(p.view, 1);
  }
  v->addLayout(plots, 2);

  // Homing joint by joint (machines whose joints are not one per axis).
  auto* row = new QHBoxLayout();
  const int joints = static_cast<int>(s_.config.joints.size());
  for (int j = 0; j < joints; ++j) {
    auto* b = ui::button(QString("Home J%1").arg(j), ("homeJoint_" + std::to_string(j)).c_str(), this);
    connect(b, &QPushButton::clicked, this, [this, j]() {
      s_.send_in_mode(ipc::TaskMode::Manual, {commands::home(j)}, "home joint " + std::to_string(j));
    });
    row->addWidget(b);
    home_.push_back(b);
  }
  row->addStretch(1);
  auto* unhome = ui::button("Unhome all", "unhomeAll", this);
  connect(unhome, &QPushButton::clicked, this,
          [this]() { s_.send_in_mode(ipc::TaskMode::Manual, {commands::unhome(-1)}, "unhome all"); });
  row->addWidget(unhome);
  home_.push_back(unhome);
  v->addLayout(row);
}

DrivesPage::~DrivesPage() = default;

void DrivesPage::sample(double t_s) {
  if (!s_.connected) return;
  DriveCharts& c = *charts_;
  c.now_s = t_s;
  for (int i = 0; i < kDriveSlots; ++i) {
    const ipc::DriveStatus& d = s_.status.drives[i];
    DriveTrends& t = c.trends[static_cast<std::size_t>(i)];
    if (!d.present) {
      t = DriveTrends{};
      continue;
    }
    t.following_error.add(t_s, d.following_error);
    t.torque.add(t_s, d.torque_percent);
    t.velocity.add(t_s, drive_velocity_value(d));
  }
}

namespace {
QColor trend_color(int slot) {
  static const QColor kColors[] = {QColor(0x1f, 0x77, 0xb4), QColor(0x2c, 0xa0, 0x2c), QColor(0xd6, 0x27, 0x28),
                                   QColor(0x94, 0x67, 0xbd), QColor(0xff, 0x7f, 0x0e), QColor(0x8c, 0x56, 0x4b),
                                   QColor(0xe3, 0x77, 0xc2), QColor(0x7f, 0x7f, 0x7f), QColor(0xbc, 0xbd, 0x22),
                                   QColor(0x17, 0xbe, 0xcf)};
  return kColors[slot % 10];
}

// The series of one plot: the drives present, their points, and the axes
// over the window and the values (a flat trend gets a little room).
void show_plot(DriveCharts::Plot& p, const std::array<DriveTrends, kDriveSlots>& trends,
               const std::array<QString, kDriveSlots>& names, double now_s, const Trend DriveTrends::*which) {
  double lo = 0, hi = 0;
  bool any = false;
  for (int i = 0; i < kDriveSlots; ++i) {
    const Trend& t = trends[static_cast<std::size_t>(i)].*which;
    QLineSeries*& series = p.series[static_cast<std::size_t>(i)];
    if (t.points().empty() || names[static_cast<std::size_t>(i)].isEmpty()) {
      if (series) series->clear();
      continue;
    }
    if (!series) {
      series = new QLineSeries();
      series->setColor(trend_color(i));
      p.chart->addSeries(series);
      series->attachAxis(p.x);
      series->attachAxis(p.y);
    }
    if (series->name() != names[static_cast<std::size_t>(i)]) series->setName(names[static_cast<std::size_t>(i)]);
    QList<QPointF> pts;
    pts.reserve(static_cast<qsizetype>(t.points().size()));
    for (const auto& [ts, v] : t.points()) pts.append(QPointF(ts - now_s, v));
    series->replace(pts);
    const auto [a, b] = t.range();
    lo = any ? std::min(lo, a) : a;
    hi = any ? std::max(hi, b) : b;
    any = true;
  }
  const double pad = std::max(1e-6, (hi - lo) * 0.1);
  p.x->setRange(-30, 0);
  p.y->setRange(lo - pad, hi + pad);
}
}  // namespace

void DrivesPage::refresh() {
  for (auto* b : home_) b->setEnabled(s_.is_on() && s_.is_idle());
  const auto& st = s_.status;
  const int joints = s_.connected ? std::min<int>(st.motion.joints, kMaxJoints) : static_cast<int>(s_.config.joints.size());
  bool any_drive = false;
  for (const auto& d : st.drives) any_drive = any_drive || d.present;
  const bool spindle_drive = std::any_of(std::begin(st.drives), std::end(st.drives), [](const ipc::DriveStatus& d) { return d.present && d.joint < 0; });
  const int rows = joints + (spindle_drive ? 1 : 0);
  if (table_->rowCount() != rows) table_->setRowCount(rows);
  ui::set_text(note_, !s_.connected ? "No controller."
                      : any_drive   ? "CiA-402 drives as the controller reports them; following error from motion and from the drive."
                                    : "No drive data in the status (simulated joints): following error from motion only.");
  const int dec = s_.config.dro_decimals(s_.config.machine_inch) + 1;
  const auto set = [&](int r, int c, const QString& text, const QColor& bg = QColor(), const QString& tip = QString()) {
    QTableWidgetItem* it = table_->item(r, c);
    if (!it) {
      it = new QTableWidgetItem();
      table_->setItem(r, c, it);
    }
    if (it->text() != text) it->setText(text);
    if (it->toolTip() != tip) it->setToolTip(tip);
    if (it->background().color() != bg) it->setBackground(bg.isValid() ? QBrush(bg) : QBrush());
  };
  const auto angular = [&](int joint) {
    return joint >= 0 && joint < static_cast<int>(s_.config.joints.size()) && s_.config.joints[static_cast<std::size_t>(joint)].angular;
  };
  // The statusword of the selected drive (else the first) in full below the table.
  const QList<QTableWidgetItem*> selected = table_->selectedItems();
  const int detail_row = selected.isEmpty() ? -1 : selected.front()->row();
  QString detail;
  for (int r = 0; r < rows; ++r) {
    const bool is_spindle = r >= joints;
    const ipc::DriveStatus* d = nullptr;
    int slot = -1;
    for (int i = 0; i < kDriveSlots; ++i) {
      const auto& dr = st.drives[i];
      if (dr.present && (is_spindle ? dr.joint < 0 : dr.joint == r)) {
        d = &dr;
        slot = i;
      }
    }
    const std::string pos_unit = drive_position_unit(angular(r), s_.config.machine_inch);
    const std::string vel_unit = drive_velocity_unit(is_spindle, angular(r), s_.config.machine_inch);
    QString ferror;
    if (is_spindle) {
      set(r, kColJoint, "spindle");
    } else {
      const auto& j = st.joints[r];
      const QString axis = j.axis >= 0 && j.axis < kNumAxes ? QString(kAxisLetters[j.axis]) : QString("—");
      set(r, kColJoint, QString("%1 %2\n%3").arg(r).arg(axis, j.homing ? "homing" : j.homed ? "homed" : "unhomed"),
          j.homed ? QColor() : QColor(0xff, 0xe0, 0xe0));
      const bool near = j.ferror_limit > 0 && std::fabs(j.ferror_current) > 0.5 * j.ferror_limit;
      ferror = QString("%1 / %2\nmax %3").arg(s_.number(j.ferror_current, dec), s_.number(j.ferror_limit, dec),
                                               s_.number(j.ferror_highmark, dec));
      if (d) ferror += QString(" · drive %1").arg(s_.number(d->following_error, dec));
      if (angular(r)) ferror += " " + ui::qs(pos_unit);  // the header's unit is the linear one
      set(r, kColFerror, ferror, near ? QColor(0xff, 0xe8, 0xb0) : QColor());
    }
    if (!d) {
      set(r, kColDrive, "— (no drive data)");
      set(r, kColStatusword, "");
      set(r, kColFault, "");
      set(r, kColTorque, "");
      if (!is_spindle) set(r, kColVelocity, s_.number(st.joints[r].velocity, 3) + " " + ui::qs(vel_unit));
      continue;
    }
    const bool fault = d->state == kDriveStateFault || d->state == kDriveStateFaultReaction;
    static const char* kModes[] = {"", "PP", "", "PV", "PT", "", "HM", "IP", "CSP", "CSV", "CST"};
    const QString name = d->name.empty() ? QString("drive") : ui::qs(d->name.view());
    charts_->names[static_cast<std::size_t>(slot)] = is_spindle ? name + " (spindle)" : QString("%1 (J%2)").arg(name).arg(r);
    set(r, kColDrive, QString("%1: %2\nmode %3 %4").arg(name, drive_state_name(d->state)).arg(d->mode).arg(d->mode <= 10 ? kModes[d->mode] : ""),
        fault ? QColor(0xff, 0xb0, 0xb0) : d->state == 4 ? QColor(0xd0, 0xf0, 0xd0) : QColor());
    set(r, kColStatusword, ui::qs(statusword_short(d->statusword)), QColor(),
        ui::qs(statusword_readout(d->statusword)) + QString("\ncontrolword 0x%1").arg(d->controlword, 4, 16, QChar('0')));
    if (r == detail_row || (detail_row < 0 && detail.isEmpty())) {
      detail = QString("<b>%1</b> statusword %2").arg(name.toHtmlEscaped(), ui::qs(statusword_readout(d->statusword)).toHtmlEscaped());
    }
    set(r, kColFault, d->error_code ? QString("0x%1 %2").arg(d->error_code, 4, 16, QChar('0'))
                                          .arg(d->fault_text.empty() ? QString::fromStdString(decode_drive_error(d->error_code))
                                                                     : ui::qs(d->fault_text.view()))
                                    : QString(), fault ? QColor(0xff, 0xb0, 0xb0) : QColor());
    if (is_spindle) set(r, kColFerror, "");
    set(r, kColTorque, s_.number(d->torque_percent, 1) + " %");
    set(r, kColVelocity, s_.number(drive_velocity_value(*d), is_spindle ? 0 : 3) + " " + ui::qs(vel_unit));
  }
  ui::set_text(detail_, detail);
  DriveCharts& c = *charts_;
  QString legend;
  for (int i = 0; i < kDriveSlots; ++i) {
    if (c.names[static_cast<std::size_t>(i)].isEmpty() || !st.drives[i].present) continue;
    legend += QString("<span style='color:%1'>&#9632;</span> %2 &nbsp; ")
                  .arg(trend_color(i).name(), c.names[static_cast<std::size_t>(i)].toHtmlEscaped());
  }
  ui::set_text(legend_, legend.isEmpty() ? QString() : "Trends, last 30 s: " + legend);
  show_plot(c.plots[0], c.trends, c.names, c.now_s, &DriveTrends::following_error);
  show_plot(c.plots[1], c.trends, c.names, c.now_s, &DriveTrends::torque);
  show_plot(c.plots[2], c.trends, c.names, c.now_s, &DriveTrends::velocity);
}

}  // namespace cnc::hmi
