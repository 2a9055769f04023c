#include "foxglove/annotations.hpp"

namespace foxglove {

namespace {

namespace fx = foxglove_msgs::msg::dds_;

fx::Color_ colour(double r, double g, double b, double a = 1.0) {
  fx::Color_ c;
  c.r(r), c.g(g), c.b(b), c.a(a);
  return c;
}
fx::Point2_ point(double u, double v) {
  fx::Point2_ p;
  p.x(u + 0.5), p.y(v + 0.5);  // Foxglove's origin: the top-left pixel's corner; ours: its centre
  return p;
}
fx::CircleAnnotation_ ring(const builtin_interfaces::msg::dds_::Time_& stamp, double u, double v, double diameter,
                           const fx::Color_& outline) {
  fx::CircleAnnotation_ c;
  c.timestamp(stamp), c.position(point(u, v)), c.diameter(diameter), c.thickness(1.5);
  c.outline_color(outline), c.fill_color(colour(0, 0, 0, 0));
  return c;
}

}  // namespace

Annotations::Annotations(Sink sink, std::function<bool()> wanted) : sink_(std::move(sink)), wanted_(std::move(wanted)) {}

void Annotations::on_status(const cell_msgs::msg::dds_::SimStatus_& s) {
  std::lock_guard<std::mutex> l(m_);
  if (s.state() != 3) return;  // SimStatus TEACHING: the teach frame
  teach_ = key(s.header().stamp());
  for (const auto& x : recent_)
    if (key(x.header().stamp()) == teach_) learn(x);
}

void Annotations::on_spots(const cell_msgs::msg::dds_::DecodedSpots_& x) {
  std::lock_guard<std::mutex> l(m_);
  if (key(x.header().stamp()) == teach_) learn(x);
  recent_.push_back(x);
  if (recent_.size() > 16) recent_.pop_front();
  if (!wanted_ || wanted_()) sink_(draw(x));
}

void Annotations::learn(const cell_msgs::msg::dds_::DecodedSpots_& x) {
  desired_.clear();
  for (const auto& s : x.spots()) desired_[{s.row(), s.col()}] = {s.u(), s.v()};
}

Annotations::Drawn Annotations::draw(const cell_msgs::msg::dds_::DecodedSpots_& x) const {
  const auto& stamp = x.header().stamp();
  const fx::Color_ gold = colour(1.0, 0.85, 0.1), white = colour(1, 1, 1);
  Drawn a;
  for (const auto& [id, uv] : desired_) a.circles().push_back(ring(stamp, uv.first, uv.second, 12, gold));
  fx::PointsAnnotation_ errors;  // a line list: current, desired, current, desired, ...
  errors.timestamp(stamp), errors.type(4), errors.thickness(1.5), errors.outline_color(gold);
  for (const auto& s : x.spots()) {
    a.circles().push_back(ring(stamp, s.u(), s.v(), 10, white));
    fx::TextAnnotation_ t;
    t.timestamp(stamp), t.position(point(s.u() + 6, s.v() - 4));
    t.text(std::to_string(s.row()) + "," + std::to_string(s.col())), t.font_size(9);
    t.text_color(white), t.background_color(colour(0, 0, 0, 0.5));
    a.texts().push_back(t);
    if (const auto d = desired_.find({s.row(), s.col()}); d != desired_.end()) {
      errors.points().push_back(point(s.u(), s.v()));
      errors.points().push_back(point(d->second.first, d->second.second));
    }
  }
  if (!errors.points().empty()) a.points().push_back(errors);
  return a;
}

}  // namespace foxglove
