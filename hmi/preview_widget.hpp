// The 3-D preview of the loaded program and the live backplot, drawn with
// QPainter in an orthographic projection: the machine's soft-limit box, the
// program path (rapids, feeds, arcs, probes in their own colours, the
// executing line highlighted), the path the tool really took, the tool, the
// work origin and the run-from-line approach. Views P/X/Y/Z (lathe: the XZ
// plane), zoom, pan and rotate by mouse, wheel, pinch or buttons; a warning
// when the program leaves the soft limits. The static part is cached in an
// image, so a running machine only repaints the live part.
#pragma once

#include <QImage>
#include <QWidget>
#include <memory>
#include <unordered_map>
#include <vector>

#include "core/util/pose.hpp"
#include "hmi/preview_path.hpp"

namespace cnc::hmi {

class PreviewWidget : public QWidget {
  Q_OBJECT
 public:
  enum class View { Perspective, X, Y, Z, Lathe };

  explicit PreviewWidget(QWidget* parent = nullptr);

  void set_lathe(bool lathe, bool back_tool);
  // Soft limits of X, Y, Z (machine units).
  void set_limits(const Pose& min, const Pose& max);
  void set_path(std::shared_ptr<const PreviewResult> path);
  void clear_path();
  const PreviewResult* path() const { return path_.get(); }
  // Live data, once per cycle; repaints only when something visible moved.
  void set_tool(const Pose& machine, bool valid, double tool_length);
  void set_origin(const Pose& machine, bool valid);
  void set_executing_line(int line);
  // Adds a point to the live plot; it is drawn at the next flush().
  void add_backplot(const Pose& machine);
  void flush();
  void clear_backplot();
  std::size_t backplot_size() const { return backplot_.size(); }
  // Run from line: the approach from `from` to `to` (up, across, down).
  void set_approach(const Pose& from, const Pose& to);
  void clear_approach();
  void set_status_text(const QString& text);

  void set_view(View v);
  View view() const noexcept { return view_; }
  void zoom(double factor);
  void fit();
  // Warning text when the program leaves the limits (empty: none).
  QString limit_warning() const;

 protected:
  void paintEvent(QPaintEvent*) override;
  void resizeEvent(QResizeEvent*) override;
  void mousePressEvent(QMouseEvent*) override;
  void mouseMoveEvent(QMouseEvent*) override;
  void wheelEvent(QWheelEvent*) override;
  bool event(QEvent*) override;

 private:
  struct Vec {
    double x, y, z;
  };
  QPointF project(double x, double y, double z) const;
  QPointF project(const Pose& p) const { return project(p[0], p[1], p[2]); }
  void set_rotation(double yaw_deg, double pitch_deg);
  void render_static();
  void invalidate();
  void draw_box(class QPainter& p, const Pose& min, const Pose& max) const;

  // Camera: rows of the rotation matrix (screen x, screen y, depth), scale in
  // pixels per unit, the model point at the widget's centre plus a pan.
  double m_[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  double yaw_ = -35, pitch_ = -60;
  double scale_ = 1;
  Vec center_{0, 0, 0};
  QPointF pan_{0, 0};
  View view_ = View::Perspective;
  bool lathe_ = false, back_tool_ = false;
  bool fitted_ = false;

  Pose limit_min_, limit_max_;
  bool have_limits_ = false;
  std::shared_ptr<const PreviewResult> path_;
  std::unordered_map<int, std::vector<uint32_t>> line_points_;  // line -> indexes of points ending a move of it
  int executing_line_ = 0;
  std::vector<Vec> backplot_;
  bool backplot_dirty_ = false;
  Pose tool_{}, origin_{};
  bool tool_valid_ = false, origin_valid_ = false;
  double tool_length_ = 0;
  QPointF tool_pixel_{-1e9, -1e9};
  bool approach_ = false;
  Pose approach_from_{}, approach_to_{};
  QString status_text_;

  QImage cache_;
  bool cache_valid_ = false;
  QPoint last_mouse_;
  Qt::MouseButton drag_button_ = Qt::NoButton;
};

}  // namespace cnc::hmi
