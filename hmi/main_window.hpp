// The operator screen's main window: status strip on top, DRO, manual
// controls and overrides on the left, the pages (program with 3-D preview,
// MDI, tools, offsets, alarms, drives, embedded panels) on the right, the
// program controls at the bottom. One timer at [DISPLAY]CYCLE_TIME reads
// the status and the message channel and refreshes what is visible;
// commands are sent without waiting and their answers followed by the
// tracker. Links only the client side (MachineLink, the halcmd channel).
#pragma once

#include <QMainWindow>
#include <QPointer>
#include <atomic>
#include <map>
#include <memory>
#include <thread>

#include "hmi/alarms.hpp"
#include "hmi/commands.hpp"
#include "hmi/config.hpp"
#include "hmi/hal_channel.hpp"
#include "hmi/jog.hpp"
#include "hmi/link.hpp"
#include "hmi/mdi_history.hpp"
#include "hmi/screen.hpp"
#include "hmi/user_dialogs.hpp"

class QTabWidget;
class QTimer;
class QMessageBox;
class QProcess;
class QSplitter;

namespace cnc::hmi {

class StatusStrip;
class DroPanel;
class ManualPanel;
class OverridePanel;
class ProgramBar;
class ProbePage;
class ScopePage;
class MdiPage;
class ToolPage;
class OffsetsPage;
class AlarmsPage;
class DrivesPage;
class PreviewWidget;
class ProgramText;
struct PreviewResult;

class MainWindow : public QMainWindow {
  Q_OBJECT
 public:
  struct Options {
    bool start_timer = true;      // tests drive tick() themselves
    bool hal = true;              // create the screen's pins, run POSTGUI (needs a HalExecutor)
    bool embed_tabs = true;       // start EMBED_TAB_COMMANDs
    bool number_comma = false;    // show numbers with a decimal comma
  };

  MainWindow(HmiConfig config, UserDialogConfig dialogs, std::unique_ptr<MachineLink> link, HalExecutor hal,
             Options options);
  ~MainWindow() override;

  // One cycle: status, messages, command answers, refresh.
  void tick();
  // Opens a program (through its [FILTER] program when one is set).
  void open_program(const QString& path);
  // Shows the run-from-line approach, then asks the operator to confirm.
  void request_run_from_line(int line);

  Screen& screen() { return screen_; }
  AlarmLog& alarms() { return alarms_; }
  JogController& jog() { return jog_; }
  QTabWidget* tabs() const { return tabs_; }
  PreviewWidget* preview() const { return preview_; }
  ProgramText* program_text() const { return program_text_; }
  bool preview_busy() const { return preview_running_; }
  bool hal_setup_pending() const { return hal_pending_ > 0; }
  int shown_user_dialogs() const { return static_cast<int>(user_boxes_.size()); }
  const HmiConfig& config() const { return config_; }

 protected:
  bool eventFilter(QObject* watched, QEvent* e) override;
  void changeEvent(QEvent* e) override;
  void closeEvent(QCloseEvent* e) override;

 private:
  void build();
  void on_connected();
  void load_program(const QString& path);
  void start_preview(const QString& path);
  // The planner's motion time of the program (cnc-estimate, in the
  // background), shown with the program's progress.
  void start_estimate(const QString& path);
  void preview_ready(std::shared_ptr<const PreviewResult> result, unsigned generation);
  void run_filter(const QString& path, const struct FilterProgram& filter);
  void choose_program();
  void hal_setup();
  void hal_replied(int tag, const QString& line, bool ok, const QString& text);
  void apply_dialog_actions(const std::vector<UserDialogLogic::Action>& actions);
  void refresh_pages();
  void sample_backplot();
  bool handle_key(QKeyEvent* e, bool press);
  void log_to_file(const LogEntry& e);
  void check_run_from_line();

  HmiConfig config_;
  Options options_;
  std::unique_ptr<MachineLink> link_;
  CommandTracker tracker_;
  AlarmLog alarms_;
  JogController jog_;
  MdiHistory history_;
  Screen screen_;
  std::unique_ptr<HalChannel> hal_;
  UserDialogLogic dialogs_;
  int hal_pending_ = 0;
  std::map<const UserMessage*, QPointer<QMessageBox>> user_boxes_;

  QTimer* timer_ = nullptr;
  QTimer* backplot_timer_ = nullptr;
  StatusStrip* strip_ = nullptr;
  DroPanel* dro_ = nullptr;
  ManualPanel* manual_ = nullptr;
  OverridePanel* overrides_ = nullptr;
  ProgramBar* bar_ = nullptr;
  QTabWidget* tabs_ = nullptr;
  PreviewWidget* preview_ = nullptr;
  ProgramText* program_text_ = nullptr;
  MdiPage* mdi_ = nullptr;
  ToolPage* tools_ = nullptr;
  OffsetsPage* offsets_ = nullptr;
  AlarmsPage* alarms_page_ = nullptr;
  ProbePage* probe_ = nullptr;
  ScopePage* scope_ = nullptr;
  DrivesPage* drives_ = nullptr;
  QWidget* program_page_ = nullptr;

  bool connected_ = false;
  bool ever_connected_ = false;
  std::string last_disconnect_reason_;
  std::string shown_file_;
  ipc::InterpState last_interp_ = ipc::InterpState::Idle;
  uint64_t alarms_revision_ = ~0ULL;
  int pending_run_from_line_ = 0;
  QPointer<QMessageBox> run_from_line_box_;
  std::string preview_key_;

  std::thread preview_thread_;
  std::shared_ptr<std::atomic<bool>> preview_cancel_;
  unsigned preview_generation_ = 0;
  bool preview_running_ = false;
  QProcess* filter_ = nullptr;
  QProcess* estimate_ = nullptr;
  std::vector<QProcess*> embedded_;
  std::FILE* log_file_ = nullptr;
};

}  // namespace cnc::hmi
