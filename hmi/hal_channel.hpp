// The screen's halcmd channel: creates its own HAL pins (newcomp/newpin),
// runs the POSTGUI files and commands, writes its pins (setr) and polls
// them. The controller answers over a Unix socket that can block, so every
// request runs on a worker thread; answers come back as Qt signals on the
// UI thread. Requests run in the order they were made.
#pragma once

#include <QObject>
#include <QString>
#include <functional>
#include <memory>
#include <string>

#include "core/ipc/admin.hpp"

namespace cnc::hmi {

// Runs one halcmd line; may throw (no controller, socket closed).
using HalExecutor = std::function<ipc::AdminReply(const std::string& line)>;

// An executor over ipc::AdminClient for an instance; reconnects after errors.
HalExecutor make_admin_executor(const std::string& instance);

class HalChannel : public QObject {
  Q_OBJECT
 public:
  explicit HalChannel(HalExecutor executor, QObject* parent = nullptr);
  ~HalChannel() override;

  // Queues a line; `tag` comes back with the answer.
  void request(const QString& line, int tag = 0);
  // Polls "show pin <pattern>" every `period_ms` (0 stops); the answer is
  // signalled only when it changed.
  void set_poll(const QString& pattern, int period_ms);

 signals:
  void replied(int tag, const QString& line, bool ok, const QString& text);
  void polled(const QString& text);

 private:
  struct Shared;
  std::shared_ptr<Shared> shared_;
};

}  // namespace cnc::hmi
