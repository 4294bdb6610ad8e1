#include "hmi/program_text.hpp"

#include <QFile>
#include <QMouseEvent>
#include <QPainter>
#include <QScroller>
#include <QTextBlock>

namespace cnc::hmi {
namespace {

class NumberArea : public QWidget {
 public:
  explicit NumberArea(ProgramText* text) : QWidget(text), text_(text) {}
  QSize sizeHint() const override { return QSize(text_->number_width(), 0); }

 protected:
  void paintEvent(QPaintEvent* e) override { text_->paint_numbers(e); }

 private:
  ProgramText* text_;
};

}  // namespace

ProgramText::ProgramText(QWidget* parent) : QPlainTextEdit(parent), numbers_(new NumberArea(this)) {
  setObjectName("programText");
  setReadOnly(true);
  setFocusPolicy(Qt::NoFocus);
  setLineWrapMode(QPlainTextEdit::NoWrap);
  setTextInteractionFlags(Qt::NoTextInteraction);
  setCenterOnScroll(false);
  QFont f("DejaVu Sans Mono");
  f.setStyleHint(QFont::Monospace);
  f.setPointSize(10);
  setFont(f);
  QScroller::grabGesture(viewport(), QScroller::TouchGesture);
  connect(this, &QPlainTextEdit::blockCountChanged, this, [this](int) { setViewportMargins(number_width(), 0, 0, 0); });
  connect(this, &QPlainTextEdit::updateRequest, this, [this](const QRect& r, int dy) {
    if (dy) numbers_->scroll(0, dy);
    else numbers_->update(0, r.y(), numbers_->width(), r.height());
  });
  setViewportMargins(number_width(), 0, 0, 0);
}

int ProgramText::number_width() const {
  int digits = 1;
  for (int n = std::max(1, blockCount()); n >= 10; n /= 10) ++digits;
  return 10 + fontMetrics().horizontalAdvance(QLatin1Char('9')) * std::max(digits, 3);
}

void ProgramText::resizeEvent(QResizeEvent* e) {
  QPlainTextEdit::resizeEvent(e);
  const QRect cr = contentsRect();
  numbers_->setGeometry(QRect(cr.left(), cr.top(), number_width(), cr.height()));
}

void ProgramText::paint_numbers(QPaintEvent* e) {
  QPainter p(numbers_);
  p.fillRect(e->rect(), QColor(0xec, 0xec, 0xec));
  QTextBlock block = firstVisibleBlock();
  int top = qRound(blockBoundingGeometry(block).translated(contentOffset()).top());
  const int h = fontMetrics().height();
  while (block.isValid() && top <= e->rect().bottom()) {
    const int line = block.blockNumber() + 1;
    if (block.isVisible() && top + h >= e->rect().top()) {
      p.setPen(line == executing_ ? QColor(0, 0, 160) : QColor(120, 120, 120));
      p.drawText(0, top, numbers_->width() - 5, h, Qt::AlignRight, QString::number(line));
    }
    top += qRound(blockBoundingRect(block).height());
    block = block.next();
  }
}

bool ProgramText::load(const QString& path, qint64 max_bytes, QString& error) {
  QFile f(path);
  if (!f.open(QIODevice::ReadOnly)) {
    error = f.errorString();
    return false;
  }
  QByteArray data = f.read(max_bytes > 0 ? max_bytes : f.size());
  const bool cut = !f.atEnd();
  QString text = QString::fromUtf8(data);
  if (text.endsWith('\n')) text.chop(1);
  if (cut) text += QString("\n(... the rest of the file, %1 bytes, is not shown)").arg(f.size() - data.size());
  path_ = path;
  executing_ = read_ahead_ = selected_ = 0;
  setPlainText(text);
  update_selections();
  return true;
}

void ProgramText::clear_program() {
  path_.clear();
  executing_ = read_ahead_ = selected_ = 0;
  clear();
}

void ProgramText::set_lines(int executing, int read_ahead) {
  if (executing == executing_ && read_ahead == read_ahead_) return;
  const bool moved = executing != executing_;
  executing_ = executing;
  read_ahead_ = read_ahead;
  update_selections();
  if (moved && executing > 0) {
    const QTextBlock b = document()->findBlockByNumber(executing - 1);
    if (b.isValid()) {
      // Follow the executing line: keep it visible with some context below.
      QTextCursor c(b);
      setTextCursor(c);
      const QTextBlock ahead = document()->findBlockByNumber(std::min(blockCount(), executing + 4) - 1);
      if (ahead.isValid()) {
        setTextCursor(QTextCursor(ahead));
        ensureCursorVisible();
      }
      setTextCursor(c);
      ensureCursorVisible();
    }
  }
  numbers_->update();
}

void ProgramText::set_selected_line(int line) {
  if (line == selected_) return;
  selected_ = line;
  update_selections();
}

void ProgramText::mousePressEvent(QMouseEvent* e) {
  const int line = cursorForPosition(e->position().toPoint()).blockNumber() + 1;
  set_selected_line(line);
  emit lineSelected(line);
}

void ProgramText::update_selections() {
  QList<QTextEdit::ExtraSelection> list;
  const auto add = [&](int line, const QColor& color) {
    if (line <= 0) return;
    const QTextBlock b = document()->findBlockByNumber(line - 1);
    if (!b.isValid()) return;
    QTextEdit::ExtraSelection sel;
    sel.format.setBackground(color);
    sel.format.setProperty(QTextFormat::FullWidthSelection, true);
    sel.cursor = QTextCursor(b);
    list.append(sel);
  };
  add(selected_, QColor(0xff, 0xd8, 0xa8));
  if (read_ahead_ != executing_) add(read_ahead_, QColor(0xf2, 0xf2, 0xc8));
  add(executing_, QColor(0x9c, 0xd0, 0xff));
  setExtraSelections(list);
}

}  // namespace cnc::hmi
