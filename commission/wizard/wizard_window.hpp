// The commissioning wizard's window (docs/commissioning.md, "The wizard"):
// one page per step (1 bus ... 9 write), back/next, the progress over the
// nine steps (a step is done when the state file has its result), and a
// live status strip (E-stop chain, drive states, joint positions) from the
// controller's shared segment. Every action of a page runs a subcommand of
// `cnc-commission` as a child process (ChildRun) with the command line the
// step runner builds, shows its progress and result, and reloads the state.
#pragma once

#include <QMainWindow>
#include <QProcess>
#include <QPushButton>
#include <QString>
#include <functional>
#include <memory>

#include "commission/state.hpp"
#include "commission/wizard/step_runner.hpp"

class QLabel;
class QListWidget;
class QPlainTextEdit;
class QProgressBar;
class QStackedWidget;
class QTimer;

namespace cnc::hmi {
class MachineLink;
}

namespace cnc::commission::wizard {

// One run of `cnc-commission` with its output collected; interrupt() sends
// SIGINT (the subcommand's abort: machine off, nothing saved).
class ChildRun : public QObject {
  Q_OBJECT
 public:
  explicit ChildRun(QObject* parent = nullptr);
  ~ChildRun() override;
  // False (nothing started) while a run is going.
  bool start(const QString& program, const Argv& args);
  void interrupt();
  bool running() const { return proc_.state() != QProcess::NotRunning; }
  QString command_line() const { return command_; }

 signals:
  void started();
  void progress(int index, int count, const QString& text);
  void output(const QString& line);
  void finished(const cnc::commission::wizard::StepResult& result);

 private:
  QProcess proc_;
  OutputCollector out_;
  bool abort_requested_ = false;
  QString command_;
  std::size_t shown_lines_ = 0;
};

// A button that runs while it is held: press starts, release (or the
// window losing focus) interrupts (HoldToRun).
class HoldToRunButton : public QPushButton {
  Q_OBJECT
 public:
  explicit HoldToRunButton(const QString& text, QWidget* parent = nullptr);
  HoldToRun& protocol() { return hold_; }

 signals:
  void startRequested();
  void interruptRequested();

 protected:
  void focusOutEvent(QFocusEvent* e) override;

 private:
  void on_press();
  void on_release();
  HoldToRun hold_;
};

struct WizardOptions {
  QString state_file = "commission.json";
  QString program;          // cnc-commission (default: beside this program)
  QString config_dir;       // where write and bring-up put the configuration
  QString instance;         // the controller's instance (default $CNC_INSTANCE)
  int status_period_ms = 200;
};

class StepPage;

class WizardWindow : public QMainWindow {
  Q_OBJECT
 public:
  WizardWindow(WizardOptions options, std::unique_ptr<hmi::MachineLink> link, QWidget* parent = nullptr);
  ~WizardWindow() override;
  void show_step(int step);
  int current_step() const;
  StepPage* page(int step) const;
  const State& state() const { return state_; }
  const std::array<bool, kSteps>& done() const { return done_; }
  const WizardOptions& options() const { return options_; }
  const CommandBuilder& builder() const { return builder_; }
  // Reads the state file again and updates the pages and the progress.
  void reload_state();
  void update_status();

 private:
  WizardOptions options_;
  CommandBuilder builder_;
  std::unique_ptr<hmi::MachineLink> link_;
  State state_;
  std::array<bool, kSteps> done_{};
  QListWidget* steps_ = nullptr;
  QProgressBar* overall_ = nullptr;
  QStackedWidget* stack_ = nullptr;
  QPushButton *back_ = nullptr, *next_ = nullptr;
  QLabel *estop_ = nullptr, *drives_ = nullptr, *positions_ = nullptr, *state_error_ = nullptr;
  QTimer* timer_ = nullptr;
  std::vector<StepPage*> pages_;
};

// What every page has: its inputs above, then the output of its last run
// (progress bar, result line, the child's lines).
class StepPage : public QWidget {
  Q_OBJECT
 public:
  StepPage(WizardWindow& w, int step, const QString& intro);
  int step() const { return step_; }
  virtual void refresh(const State&) {}
  ChildRun& child() { return *child_; }
  QLabel* result_label() const { return result_; }

 protected:
  // Runs a subcommand; `build` makes its command line (an input error is
  // shown and nothing starts); `then` sees the result after the state is
  // reloaded. False when nothing started (an input error, a run still
  // going; `then` is not called then).
  bool run(const std::function<Argv()>& build, std::function<void(const StepResult&)> then = {});
  void show_error(const QString& text);
  QWidget* inputs() const { return inputs_; }
  WizardWindow& w_;

 private:
  int step_;
  QWidget* inputs_;
  QProgressBar* progress_;
  QPushButton* stop_;
  QLabel* result_;
  QPlainTextEdit* output_;
  ChildRun* child_;
  std::function<void(const StepResult&)> then_;
};

// The page of step 0..8 (pages.cpp).
StepPage* make_page(WizardWindow& w, int step);

}  // namespace cnc::commission::wizard
