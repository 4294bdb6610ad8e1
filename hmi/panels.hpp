// The panels of the operator screen. Each shows part of the status and
// sends commands through the Screen; refresh() is called once per cycle
// with the new status (only for visible pages where that costs anything).
#pragma once

#include <QWidget>
#include <array>
#include <memory>
#include <vector>

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

}  // namespace cnc::hmi
