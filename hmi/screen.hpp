// What the panels of the operator screen share: the configuration, the
// latest status, the command tracker, the jog state machine, the alarm log
// and the number format. Owned by MainWindow; panels keep a reference.
#pragma once

#include <QString>
#include <functional>
#include <string>
#include <vector>

#include "core/ipc/estop.hpp"
#include "core/ipc/status.hpp"
#include "core/tooltable/tool_table.hpp"
#include "hmi/alarms.hpp"
#include "hmi/commands.hpp"
#include "hmi/config.hpp"
#include "hmi/jog.hpp"
#include "hmi/numbers.hpp"

class QWidget;
class QLabel;
class QPushButton;

namespace cnc::hmi {

struct Screen {
  const HmiConfig& config;
  CommandTracker& tracker;
  JogController& jog;
  AlarmLog& alarms;
  NumberFormat numbers;
  ipc::Status status{};
  bool connected = false;
  bool show_actual = false;  // DRO and preview follow the feedback
  ipc::Liveness liveness{};  // how fresh `status` is (a stalled task cycle, motion not running)
  tooltable::ToolTable tools;  // as last read from [EMCIO]TOOL_TABLE, for display
  std::function<int64_t()> now_ns;  // CLOCK_REALTIME, for log entries
  // The planner's motion time of the program last opened (cnc-estimate),
  // -1 until known; `estimate_file` is the program it is for.
  double estimate_s = -1;
  std::string estimate_file;

  Screen(const HmiConfig& c, CommandTracker& t, JogController& j, AlarmLog& a) : config(c), tracker(t), jog(j), alarms(a) {}

  void log(LogLevel level, const std::string& text, const std::string& source = "screen");
  // Sends a command; rejections are logged by the tracker's sink.
  bool send(const ipc::Command& cmd, const std::string& what, CommandTracker::Done done = {});
  // Stops jogs and E-stops (CommandTracker::estop).
  bool estop(const std::string& what);
  // Switches to `mode` first when the controller is in another one.
  bool send_in_mode(ipc::TaskMode mode, std::vector<ipc::Command> cmds, const std::string& what,
                    CommandTracker::Done done = {});
  bool is_on() const { return connected && status.task.state == ipc::TaskState::On; }
  bool is_idle() const { return connected && status.task.interp_state == ipc::InterpState::Idle; }
  bool all_homed() const;
  std::string tool_text(int tool) const;

  QString number(double v, int decimals) const { return QString::fromStdString(numbers.fixed(v, decimals)); }
};

// Small widget helpers (touch-sized buttons, labels updated only on change).
namespace ui {
void set_text(QLabel* label, const QString& text);
void set_text(QPushButton* button, const QString& text);
void set_style(QWidget* w, const QString& sheet);
QPushButton* button(const QString& text, const char* object_name, QWidget* parent = nullptr, bool checkable = false);
inline QString qs(std::string_view s) { return QString::fromUtf8(s.data(), static_cast<int>(s.size())); }
// Whether a widget takes text from the keyboard (keyboard jog is off there).
bool is_text_input(const QWidget* w);
constexpr int kTouch = 40;  // minimum height of touch targets, pixels
}  // namespace ui

}  // namespace cnc::hmi
