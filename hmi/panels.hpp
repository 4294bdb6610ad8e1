// The panels of the operator screen. Each shows part of the status and
// sends commands through the Screen; refresh() is called once per cycle
// with the new status (only for visible pages where that costs anything).
#pragma once

#include <QWidget>
#include <array>
#include <memory>
#include <vector>

#include "hmi/probing.hpp"
#include "hmi/scope_view.hpp"
#include "hmi/screen.hpp"

class QLabel;
class QPushButton;
class QButtonGroup;
class QSlider;
class QLineEdit;
class QListWidget;
class QTableWidget;
class QPlainTextEdit;
class QSpinBox;
class QComboBox;
class QProgressBar;
class QTabWidget;

namespace cnc::hmi {

class PreviewWidget;
class ProgramText;
struct PreviewResult;

// E-stop, machine on/off, the mode strip, state, homed, alarms badge, the
// last message.
class StatusStrip : public QWidget {
  Q_OBJECT
 public:
  StatusStrip(Screen& s, QWidget* parent = nullptr);
  void refresh();
  void show_message(const QString& text, bool warning);
  void set_filter_progress(int percent);  // -1 hides
 signals:
  void alarmsClicked();

 private:
  Screen& s_;
  QPushButton* estop_;
  QPushButton* machine_;
  std::array<QPushButton*, 3> modes_{};
  QLabel* state_;
  QLabel* homed_;
  QLabel* chain_;
  QLabel* stale_;
  QPushButton* alarms_;
  QLabel* message_;
  QProgressBar* progress_;
};

// Per axis: work, machine and distance-to-go positions side by side, homed
// and limit marks, zero / set (touch-off) / home buttons.
class DroPanel : public QWidget {
  Q_OBJECT
 public:
  DroPanel(Screen& s, QWidget* parent = nullptr);
  void refresh();

 private:
  struct Row {
    int axis;
    QLabel* letter;
    QLabel* work;
    QLabel* machine;
    QLabel* dtg;
    QLabel* marks;
    QPushButton* zero;
    QPushButton* set;
    QPushButton* home;
  };
  void touch_off(int axis, double value);
  void ask_touch_off(int axis);
  std::vector<int> joints_of(int axis) const;

  Screen& s_;
  std::vector<Row> rows_;
  QLabel* work_header_;
  QLabel* machine_header_;
  QLabel* units_;
  QLabel* info_;
  QLabel* gcodes_;
  QPushButton* actual_;
};

// Home all, jogging (increments, speeds, buttons), spindle and coolant.
class ManualPanel : public QWidget {
  Q_OBJECT
 public:
  ManualPanel(Screen& s, QWidget* parent = nullptr);
  void refresh();

 private:
  void set_speed_label();
  Screen& s_;
  QPushButton* home_all_;
  QPushButton* override_limits_;
  QButtonGroup* increments_;
  QButtonGroup* angular_increments_ = nullptr;
  QSlider* speed_;
  QSlider* angular_speed_ = nullptr;
  QLabel* speed_label_;
  QLabel* angular_speed_label_ = nullptr;
  QLabel* jog_note_;
  std::vector<QPushButton*> jog_buttons_;
  QLineEdit* rpm_;
  QPushButton* flood_;
  QPushButton* mist_;
};

// Feed, rapid, spindle and maximum-velocity overrides within the INI limits.
class OverridePanel : public QWidget {
  Q_OBJECT
 public:
  OverridePanel(Screen& s, QWidget* parent = nullptr);
  void refresh();
  // Sends a slider value that changed while dragging (at most once a cycle).
  void flush();

 private:
  struct Ov {
    QSlider* slider;
    QLabel* label;
    int pending = -1;
  };
  void changed(int which, int value);
  void send(int which, int value);
  double status_value(int which) const;
  QString text(int which, int value) const;
  Screen& s_;
  std::array<Ov, 4> ov_{};
  QLabel* effective_;
};

// Cycle start, feed hold, resume, step, stop, optional stop, block delete,
// run from line, open and reload; the program's progress.
class ProgramBar : public QWidget {
  Q_OBJECT
 public:
  ProgramBar(Screen& s, QWidget* parent = nullptr);
  void refresh();
  QSpinBox* start_line() const { return line_; }
  // "From line" and the progress, placed under the program text.
  QWidget* line_row() const { return line_row_; }
 signals:
  void openRequested();
  void reloadRequested();
  void runFromLineRequested(int line);

 private:
  Screen& s_;
  QPushButton* open_;
  QPushButton* reload_;
  QPushButton* run_;
  QPushButton* pause_;
  QPushButton* resume_;
  QPushButton* step_;
  QPushButton* abort_;
  QPushButton* optional_stop_;
  QPushButton* block_delete_;
  QPushButton* run_from_;
  QSpinBox* line_;
  QLabel* progress_;
  QWidget* line_row_;
};

// MDI line, history (saved, de-duplicated) and the macro buttons.
class MdiPage : public QWidget {
  Q_OBJECT
 public:
  MdiPage(Screen& s, class MdiHistory& history, QWidget* parent = nullptr);
  void refresh();
  void submit(const QString& line);
  void run_macro(int index);

 private:
  void reload_history();
  Screen& s_;
  MdiHistory& history_;
  QLineEdit* input_;
  QPushButton* send_;
  QListWidget* list_;
  QLabel* active_;
  std::vector<QPushButton*> macros_;
};

// Tool table editor: every change goes to the controller (ToolSetOffset,
// ToolDelete, ToolLoadTable); the file is only read.
class ToolPage : public QWidget {
  Q_OBJECT
 public:
  ToolPage(Screen& s, QWidget* parent = nullptr);
  void refresh();
  void reload_file();

 private:
  void cell_edited(int row, int column);
  void fill();
  Screen& s_;
  QTableWidget* table_;
  QSpinBox* new_tool_;
  QSpinBox* new_pocket_;
  QLabel* note_;
  bool filling_ = false;
  int shown_tool_ = -1;
  std::vector<int> columns_;  // field of each column
};

// G54..G59.3 (with XY rotation) and G92, through SetWorkOffset.
class OffsetsPage : public QWidget {
  Q_OBJECT
 public:
  OffsetsPage(Screen& s, QWidget* parent = nullptr);
  void refresh();
  void reload_file();

 private:
  void cell_edited(int row, int column);
  void fill();
  Screen& s_;
  QTableWidget* table_;
  QLabel* note_;
  bool filling_ = false;
  int shown_active_ = -1;
  std::vector<int> axis_columns_;
};

// Active alarms (acknowledge) and the time-stamped log.
class AlarmsPage : public QWidget {
  Q_OBJECT
 public:
  AlarmsPage(Screen& s, QWidget* parent = nullptr);
  void refresh_alarms();
  void append_log(const LogEntry& e);

 private:
  Screen& s_;
  QListWidget* list_;
  QPlainTextEdit* log_;
  QPushButton* ack_;
  QPushButton* ack_all_;
};

// Per joint: drive state, mode, decoded statusword, fault, following
// error, torque and velocity with their units, and live trends of the
// following error, torque and velocity of every drive (QtCharts). Fits
// 1024 px wide without horizontal scrolling: long texts wrap in their cells.
class DriveCharts;
class DrivesPage : public QWidget {
  Q_OBJECT
 public:
  DrivesPage(Screen& s, QWidget* parent = nullptr);
  ~DrivesPage() override;
  void refresh();
  // Records the trends (every screen cycle, shown or not).
  void sample(double t_s);

 private:
  Screen& s_;
  QTableWidget* table_;
  QLabel* note_;
  QLabel* detail_;  // the selected drive's statusword, every bit by name
  QLabel* legend_;  // the trends' colours, by drive
  std::vector<QPushButton*> home_;
  std::unique_ptr<DriveCharts> charts_;
};

// Probing (hmi/probing.hpp): tool length on the tool setter, edges,
// corners, bore and boss centres, each optionally setting the origin of
// any coordinate system; touch-off of the current position into any
// coordinate system. The routine's stages go as MDI lines through the
// command tracker, one stage after the other; each probe's result is read
// from the status of the cycle after the stage was done.
class ProbePage : public QWidget {
  Q_OBJECT
 public:
  ProbePage(Screen& s, QWidget* parent = nullptr);
  ~ProbePage() override;
  // Every cycle (the routine runs whichever page is shown).
  void refresh();
  bool running() const;
  // Starts the routine selected on the page; false with the reason logged
  // and shown when it cannot start.
  bool start();

 private:
  void send_stage();
  void finished();
  void touch_off();
  void update_fields();
  void show_settings();
  Screen& s_;
  // [PROBE], with the tip diameter a tip calibration measured (for this
  // session: the page shows it for [PROBE]TIP_DIAMETER).
  probing::Settings probe_;
  QComboBox* kind_;
  QSpinBox* tool_;
  QComboBox* corner_x_;
  QComboBox* corner_y_;
  QLineEdit* corner_step_;
  QLineEdit* boss_diameter_;
  QLineEdit* boss_depth_;
  QLineEdit* gauge_diameter_;
  QComboBox* system_;
  QLineEdit* value_x_;
  QLineEdit* value_y_;
  QPushButton* start_;
  QPushButton* stop_;
  QLabel* stage_;
  QLabel* result_;
  QLabel* settings_;
  QComboBox* touch_axis_;
  QComboBox* touch_system_;
  QLineEdit* touch_value_;
  QPushButton* touch_button_;
  std::unique_ptr<probing::Routine> routine_;
  int wait_cycles_ = 0;  // > 0: the stage is done; its result is read when this reaches 0
};

// The controller's HAL scope (docs/hal.md, "Scope and watch") on the
// screen: pins, trigger, edge, level, pre-trigger, samples and mode
// (single, normal, auto), run and stop, the capture plotted with QtCharts
// (one line per pin against time from the trigger) and exported as CSV.
// Drives the scope with halcmd lines through the screen's HAL channel
// (hmi/scope_view.hpp builds and reads them); needs `loadrt scope` and
// `addf scope.sample servo-thread` in the machine's HAL.
class HalChannel;
class ScopePage : public QWidget {
  Q_OBJECT
 public:
  // Tags of the HAL channel's requests that belong to this page.
  static constexpr int kTagFirst = 100, kTagLast = 109;
  ScopePage(Screen& s, HalChannel* hal, QWidget* parent = nullptr);
  ~ScopePage() override;
  // Every cycle while shown or while a capture runs: polls the state.
  void refresh();
  bool capturing() const { return capturing_; }
  // Runs a capture with the page's settings; false with the reason shown.
  bool run();
  void stop();
  // Writes the last capture's CSV; false with the reason shown.
  bool export_csv(const QString& path);
  const scope::Capture* last_capture() const { return capture_.get(); }

 private:
  void replied(int tag, const QString& line, bool ok, const QString& text);
  void plot();
  Screen& s_;
  HalChannel* hal_;
  QLineEdit* pins_;
  QLineEdit* trigger_;
  QComboBox* edge_;
  QLineEdit* level_;
  QSpinBox* pre_;
  QSpinBox* samples_;
  QComboBox* mode_;
  class QCheckBox* normalise_;
  QPushButton* run_;
  QPushButton* stop_;
  QPushButton* export_;
  QLabel* state_;
  class QChartView* view_;
  std::unique_ptr<scope::Capture> capture_;
  bool capturing_ = false;
  bool state_pending_ = false;
  bool normal_mode_ = false;
  int captures_ = 0;
};

}  // namespace cnc::hmi
