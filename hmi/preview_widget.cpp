#include "hmi/preview_widget.hpp"

#include <QGestureEvent>
#include <QMouseEvent>
#include <QPainter>
#include <QPinchGesture>
#include <QWheelEvent>
#include <algorithm>
#include <array>
#include <cmath>

namespace cnc::hmi {
namespace {

const QColor kBackground(24, 26, 30);
const QColor kRapid(220, 170, 40, 170);
const QColor kFeed(235, 235, 235);
const QColor kArc(170, 220, 255);
const QColor kProbe(230, 80, 230);
const QColor kExecuting(0, 230, 255);
const QColor kBackplot(255, 70, 50);
const QColor kLimits(130, 130, 140);

QColor color_of(MoveKind k) {
  switch (k) {
    case MoveKind::Rapid: return kRapid;
    case MoveKind::Arc: return kArc;
    case MoveKind::Probe: return kProbe;
    default: return kFeed;
  }
}

}  // namespace

PreviewWidget::PreviewWidget(QWidget* parent) : QWidget(parent) {
  setObjectName("preview");
  setMinimumSize(200, 160);
  setAttribute(Qt::WA_OpaquePaintEvent);
  setFocusPolicy(Qt::NoFocus);
  grabGesture(Qt::PinchGesture);
  set_rotation(yaw_, pitch_);
}

void PreviewWidget::set_rotation(double yaw_deg, double pitch_deg) {
  yaw_ = yaw_deg;
  pitch_ = std::clamp(pitch_deg, -180.0, 0.0);
  const double y = yaw_ * M_PI / 180, p = pitch_ * M_PI / 180;
  const double c = std::cos(y), s = std::sin(y), cp = std::cos(p), sp = std::sin(p);
  const double m[3][3] = {{c, -s, 0}, {cp * s, cp * c, -sp}, {sp * s, sp * c, cp}};
  std::copy(&m[0][0], &m[0][0] + 9, &m_[0][0]);
  invalidate();
}

void PreviewWidget::set_view(View v) {
  view_ = v;
  const auto rows = [this](std::array<double, 3> r0, std::array<double, 3> r1) {
    for (int i = 0; i < 3; ++i) {
      m_[0][i] = r0[static_cast<std::size_t>(i)];
      m_[1][i] = r1[static_cast<std::size_t>(i)];
    }
    m_[2][0] = r0[1] * r1[2] - r0[2] * r1[1];
    m_[2][1] = r0[2] * r1[0] - r0[0] * r1[2];
    m_[2][2] = r0[0] * r1[1] - r0[1] * r1[0];
  };
  switch (v) {
    case View::Perspective: set_rotation(-35, -60); break;
    case View::X: rows({0, 1, 0}, {0, 0, 1}); break;
    case View::Y: rows({1, 0, 0}, {0, 0, 1}); break;
    case View::Z: rows({1, 0, 0}, {0, 1, 0}); break;
    case View::Lathe: rows({0, 0, 1}, {back_tool_ ? 1.0 : -1.0, 0, 0}); break;
  }
  fit();
}

void PreviewWidget::set_lathe(bool lathe, bool back_tool) {
  lathe_ = lathe;
  back_tool_ = back_tool;
  set_view(lathe ? View::Lathe : View::Perspective);
}

void PreviewWidget::set_limits(const Pose& min, const Pose& max) {
  limit_min_ = min;
  limit_max_ = max;
  have_limits_ = true;
  if (!fitted_) fit();
  invalidate();
}

void PreviewWidget::set_path(std::shared_ptr<const PreviewResult> path) {
  path_ = std::move(path);
  line_points_.clear();
  if (path_) {
    for (std::size_t i = 1; i < path_->points.size(); ++i) {
      const PathPoint& pt = path_->points[i];
      if (pt.kind != MoveKind::Start) line_points_[pt.line].push_back(static_cast<uint32_t>(i));
    }
  }
  fit();
}

void PreviewWidget::clear_path() {
  path_.reset();
  line_points_.clear();
  invalidate();
}

void PreviewWidget::set_tool(const Pose& machine, bool valid, double tool_length) {
  tool_ = machine;
  tool_length_ = tool_length;
  const QPointF px = project(machine);
  if (valid != tool_valid_ || std::hypot(px.x() - tool_pixel_.x(), px.y() - tool_pixel_.y()) > 0.5) {
    tool_valid_ = valid;
    tool_pixel_ = px;
    update();
  }
}

void PreviewWidget::set_origin(const Pose& machine, bool valid) {
  if (valid == origin_valid_ && machine == origin_) return;
  origin_ = machine;
  origin_valid_ = valid;
  update();
}

void PreviewWidget::set_executing_line(int line) {
  if (line == executing_line_) return;
  executing_line_ = line;
  update();
}

void PreviewWidget::add_backplot(const Pose& m) {
  const Vec v{m[0], m[1], m[2]};
  if (!backplot_.empty()) {
    const Vec& l = backplot_.back();
    const double d = std::sqrt((v.x - l.x) * (v.x - l.x) + (v.y - l.y) * (v.y - l.y) + (v.z - l.z) * (v.z - l.z));
    if (d < 0.5 / std::max(scale_, 1e-9) && d < 0.05) return;
  }
  backplot_.push_back(v);
  if (backplot_.size() > 60000) {
    // Keep the shape, halve the points.
    std::vector<Vec> half;
    half.reserve(backplot_.size() / 2 + 1);
    for (std::size_t i = 0; i < backplot_.size(); i += 2) half.push_back(backplot_[i]);
    half.push_back(backplot_.back());
    backplot_ = std::move(half);
  }
  backplot_dirty_ = true;  // drawn at the next flush(), once per screen cycle
}

void PreviewWidget::flush() {
  if (!backplot_dirty_) return;
  backplot_dirty_ = false;
  update();
}

void PreviewWidget::clear_backplot() {
  backplot_.clear();
  update();
}

void PreviewWidget::set_approach(const Pose& from, const Pose& to) {
  approach_ = true;
  approach_from_ = from;
  approach_to_ = to;
  update();
}

void PreviewWidget::clear_approach() {
  if (!approach_) return;
  approach_ = false;
  update();
}

void PreviewWidget::set_status_text(const QString& text) {
  if (text == status_text_) return;
  status_text_ = text;
  update();
}

QPointF PreviewWidget::project(double x, double y, double z) const {
  const double dx = x - center_.x, dy = y - center_.y, dz = z - center_.z;
  const double sx = m_[0][0] * dx + m_[0][1] * dy + m_[0][2] * dz;
  const double sy = m_[1][0] * dx + m_[1][1] * dy + m_[1][2] * dz;
  return QPointF(width() / 2.0 + pan_.x() + sx * scale_, height() / 2.0 + pan_.y() - sy * scale_);
}

void PreviewWidget::fit() {
  // Everything that should be visible: the limits box, the program, the tool.
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  bool any = false;
  const auto grow = [&](const Pose& p) {
    for (int i = 0; i < 3; ++i) {
      lo[i] = std::min(lo[i], p[i]);
      hi[i] = std::max(hi[i], p[i]);
    }
    any = true;
  };
  if (path_ && path_->has_extents) {
    // The program fills the view (the limits box may reach beyond it).
    grow(path_->min);
    grow(path_->max);
  } else if (have_limits_ && std::fabs(limit_max_[0] - limit_min_[0]) < 1e8) {
    grow(limit_min_);
    grow(limit_max_);
  }
  if (!any) {
    grow(Pose{});
    grow(Pose{{100, 100, 100}});
  }
  // A margin, and at least a few units (a program that is one point).
  for (int i = 0; i < 3; ++i) {
    const double pad = std::max(0.04 * (hi[i] - lo[i]), 0.5);
    lo[i] -= pad;
    hi[i] += pad;
  }
  center_ = Vec{(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2};
  double sx = 1e-9, sy = 1e-9;
  for (int c = 0; c < 8; ++c) {
    const double p[3] = {c & 1 ? hi[0] : lo[0], c & 2 ? hi[1] : lo[1], c & 4 ? hi[2] : lo[2]};
    const double d[3] = {p[0] - center_.x, p[1] - center_.y, p[2] - center_.z};
    sx = std::max(sx, std::fabs(m_[0][0] * d[0] + m_[0][1] * d[1] + m_[0][2] * d[2]));
    sy = std::max(sy, std::fabs(m_[1][0] * d[0] + m_[1][1] * d[1] + m_[1][2] * d[2]));
  }
  scale_ = std::max(1e-6, std::min((width() / 2.0 - 24) / sx, (height() / 2.0 - 30) / sy));
  pan_ = QPointF(0, 0);
  fitted_ = width() > 0;
  invalidate();
}

void PreviewWidget::zoom(double factor) {
  scale_ = std::clamp(scale_ * factor, 1e-6, 1e6);
  pan_ *= factor;
  invalidate();
}

void PreviewWidget::invalidate() {
  cache_valid_ = false;
  tool_pixel_ = project(tool_);
  update();
}

void PreviewWidget::resizeEvent(QResizeEvent*) {
  if (!fitted_) fit();
  invalidate();
}

void PreviewWidget::draw_box(QPainter& p, const Pose& a, const Pose& b) const {
  const double xs[2] = {a[0], b[0]}, ys[2] = {a[1], b[1]}, zs[2] = {a[2], b[2]};
  QPointF c[8];
  for (int i = 0; i < 8; ++i) c[i] = project(xs[i & 1], ys[(i >> 1) & 1], zs[(i >> 2) & 1]);
  const int edges[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3}, {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
  for (const auto& e : edges) p.drawLine(c[e[0]], c[e[1]]);
}

QString PreviewWidget::limit_warning() const {
  if (!path_ || path_->violations.empty()) return {};
  QString w = "Program leaves the soft limits:";
  for (const auto& v : path_->violations) {
    w += QString("\n  %1 %2 %3 (reaches %4) from line %5")
             .arg(QChar(kAxisLetters[v.axis]))
             .arg(v.above ? "above" : "below")
             .arg(v.limit, 0, 'f', 3)
             .arg(v.value, 0, 'f', 3)
             .arg(v.first_line);
  }
  return w;
}

void PreviewWidget::render_static() {
  const qreal dpr = devicePixelRatioF();
  const QSize size(std::max(1, static_cast<int>(width() * dpr)), std::max(1, static_cast<int>(height() * dpr)));
  if (cache_.size() != size) cache_ = QImage(size, QImage::Format_ARGB32_Premultiplied);
  cache_.setDevicePixelRatio(dpr);
  cache_.fill(kBackground);
  QPainter p(&cache_);
  p.setRenderHint(QPainter::Antialiasing, true);
  // Machine limits box (red when the program leaves it).
  if (have_limits_ && std::fabs(limit_max_[0] - limit_min_[0]) < 1e8) {
    const bool bad = path_ && !path_->violations.empty();
    p.setPen(QPen(bad ? QColor(200, 60, 60) : kLimits, 1, Qt::DashLine));
    draw_box(p, limit_min_, limit_max_);
  }
  if (path_ && path_->points.size() > 1) {
    std::vector<QLineF> batch[5];
    QPointF last = project(path_->points[0].x, path_->points[0].y, path_->points[0].z);
    MoveKind last_kind = MoveKind::Start;
    const auto flush = [&](int k) {
      if (batch[k].empty()) return;
      p.setPen(QPen(color_of(static_cast<MoveKind>(k)), k == static_cast<int>(MoveKind::Rapid) ? 1.0 : 1.3));
      p.drawLines(batch[k].data(), static_cast<int>(batch[k].size()));
      batch[k].clear();
    };
    for (std::size_t i = 1; i < path_->points.size(); ++i) {
      const PathPoint& pt = path_->points[i];
      const QPointF q = project(pt.x, pt.y, pt.z);
      if (pt.kind == MoveKind::Start) {
        last = q;
        continue;
      }
      // Skip moves shorter than a pixel (their end is drawn by the next one).
      if (pt.kind == last_kind && std::fabs(q.x() - last.x()) < 0.7 && std::fabs(q.y() - last.y()) < 0.7) continue;
      const int k = static_cast<int>(pt.kind);
      batch[k].emplace_back(last, q);
      if (batch[k].size() >= 4096) flush(k);
      last = q;
      last_kind = pt.kind;
    }
    for (int k = 0; k < 5; ++k) flush(k);
  }
  cache_valid_ = true;
}

void PreviewWidget::paintEvent(QPaintEvent*) {
  if (!cache_valid_ || cache_.size() != QSize(static_cast<int>(width() * devicePixelRatioF()),
                                              static_cast<int>(height() * devicePixelRatioF()))) {
    render_static();
  }
  QPainter p(this);
  p.drawImage(0, 0, cache_);
  p.setRenderHint(QPainter::Antialiasing, true);
  // The executing line.
  if (path_ && executing_line_ > 0) {
    const auto it = line_points_.find(executing_line_);
    if (it != line_points_.end()) {
      p.setPen(QPen(kExecuting, 3));
      for (uint32_t i : it->second) {
        const PathPoint& a = path_->points[i - 1];
        const PathPoint& b = path_->points[i];
        p.drawLine(project(a.x, a.y, a.z), project(b.x, b.y, b.z));
      }
    }
  }
  // Where the tool went.
  if (backplot_.size() > 1) {
    QPolygonF poly;
    poly.reserve(static_cast<int>(backplot_.size()));
    for (const Vec& v : backplot_) poly << project(v.x, v.y, v.z);
    p.setPen(QPen(kBackplot, 1.5));
    p.drawPolyline(poly);
  }
  if (approach_) {
    Pose up = approach_from_, over = approach_to_;
    up[2] = std::max(approach_from_[2], approach_to_[2]);
    over[2] = up[2];
    p.setPen(QPen(QColor(255, 150, 0), 2, Qt::DashLine));
    const QPointF pts[4] = {project(approach_from_), project(up), project(over), project(approach_to_)};
    p.drawPolyline(pts, 4);
    p.setBrush(QColor(255, 150, 0));
    p.drawEllipse(pts[3], 5, 5);
    p.setBrush(Qt::NoBrush);
  }
  if (origin_valid_) {
    const QPointF o = project(origin_);
    const double len = 24 / std::max(scale_, 1e-9);
    const QColor colors[3] = {QColor(230, 60, 60), QColor(60, 200, 60), QColor(80, 120, 255)};
    for (int a = 0; a < 3; ++a) {
      Pose e = origin_;
      e[a] += len;
      p.setPen(QPen(colors[a], 2));
      p.drawLine(o, project(e));
    }
  }
  if (tool_valid_) {
    const QPointF t = project(tool_);
    Pose top = tool_;
    top[2] += std::max(tool_length_, 30 / std::max(scale_, 1e-9));
    p.setPen(QPen(QColor(255, 255, 0), 2));
    p.drawLine(t, project(top));
    p.drawEllipse(t, 4, 4);
  }
  // Texts.
  p.setPen(QColor(200, 200, 200));
  const char* names[] = {"P", "X", "Y", "Z", "Lathe"};
  QString corner = QString("view %1").arg(names[static_cast<int>(view_)]);
  if (path_) {
    corner += QString(" · %1 blocks").arg(path_->blocks);
    if (path_->has_extents) {
      corner += QString("\nX %1..%2  Y %3..%4  Z %5..%6")
                    .arg(path_->min[0], 0, 'f', 2).arg(path_->max[0], 0, 'f', 2)
                    .arg(path_->min[1], 0, 'f', 2).arg(path_->max[1], 0, 'f', 2)
                    .arg(path_->min[2], 0, 'f', 2).arg(path_->max[2], 0, 'f', 2);
    }
  }
  p.drawText(QRect(8, height() - 40, width() - 16, 36), Qt::AlignLeft | Qt::AlignBottom, corner);
  QString top_text = status_text_;
  if (path_ && !path_->error.empty()) {
    top_text += QString("%1Interpreter: line %2: %3").arg(top_text.isEmpty() ? "" : "\n").arg(path_->error_line).arg(QString::fromStdString(path_->error));
  }
  if (path_ && path_->truncated) top_text += QString("%1Preview truncated (too large)").arg(top_text.isEmpty() ? "" : "\n");
  const QString warn = limit_warning();
  if (!warn.isEmpty()) top_text = warn + (top_text.isEmpty() ? "" : "\n" + top_text);
  if (!top_text.isEmpty()) {
    const QRect r = p.fontMetrics().boundingRect(QRect(8, 8, width() - 16, height() - 16), Qt::TextWordWrap, top_text);
    p.fillRect(r.adjusted(-4, -3, 4, 3), warn.isEmpty() ? QColor(40, 40, 60, 220) : QColor(150, 0, 0, 230));
    p.setPen(Qt::white);
    p.drawText(r, Qt::TextWordWrap, top_text);
  }
}

void PreviewWidget::mousePressEvent(QMouseEvent* e) {
  last_mouse_ = e->position().toPoint();
  drag_button_ = e->button();
}

void PreviewWidget::mouseMoveEvent(QMouseEvent* e) {
  const QPoint pos = e->position().toPoint();
  const QPoint d = pos - last_mouse_;
  last_mouse_ = pos;
  const bool rotate = drag_button_ == Qt::LeftButton && view_ == View::Perspective && !(e->modifiers() & Qt::ShiftModifier);
  if (rotate) {
    set_rotation(yaw_ + d.x() * 0.4, pitch_ + d.y() * 0.4);
  } else if (drag_button_ != Qt::NoButton) {
    pan_ += QPointF(d);
    invalidate();
  }
}

void PreviewWidget::wheelEvent(QWheelEvent* e) {
  zoom(e->angleDelta().y() > 0 ? 1.2 : 1 / 1.2);
  e->accept();
}

bool PreviewWidget::event(QEvent* e) {
  if (e->type() == QEvent::Gesture) {
    auto* g = static_cast<QGestureEvent*>(e);
    if (auto* pinch = static_cast<QPinchGesture*>(g->gesture(Qt::PinchGesture))) {
      if (pinch->changeFlags() & QPinchGesture::ScaleFactorChanged) zoom(pinch->scaleFactor());
      return true;
    }
  }
  return QWidget::event(e);
}

}  // namespace cnc::hmi
