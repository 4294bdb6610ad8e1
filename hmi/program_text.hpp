// The program's text with line numbers; the executing line (motion's) and
// the interpreter's read-ahead line are highlighted in different colours and
// the view follows the executing line. A click selects a line (for run from
// line). Read-only; never takes the keyboard focus from jogging.
#pragma once

#include <QPlainTextEdit>

namespace cnc::hmi {

class ProgramText : public QPlainTextEdit {
  Q_OBJECT
 public:
  explicit ProgramText(QWidget* parent = nullptr);
  // Reads the file (up to max_bytes; the rest is left out with a note).
  // False with `error` when it cannot be read.
  bool load(const QString& path, qint64 max_bytes, QString& error);
  void clear_program();
  // 1-based lines; 0: none.
  void set_lines(int executing, int read_ahead);
  void set_selected_line(int line);
  int selected_line() const noexcept { return selected_; }
  int executing_line() const noexcept { return executing_; }
  const QString& path() const noexcept { return path_; }
  void paint_numbers(class QPaintEvent* e);
  int number_width() const;

 signals:
  void lineSelected(int line);

 protected:
  void resizeEvent(QResizeEvent* e) override;
  void mousePressEvent(QMouseEvent* e) override;

 private:
  void update_selections();
  QWidget* numbers_;
  QString path_;
  int executing_ = 0, read_ahead_ = 0, selected_ = 0;
};

}  // namespace cnc::hmi
