#include "servo/pipeline/taught_points.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace servo {

std::vector<TaughtPoint> taught_points(const std::vector<control::Feature>& features,
                                       const Eigen::Isometry3d& world_T_camera) {
  std::vector<TaughtPoint> out;
  out.reserve(features.size());
  for (const control::Feature& f : features)
    if (f.z && std::isfinite(*f.z) && *f.z > 0)
      out.push_back({f.row, f.col, world_T_camera * Eigen::Vector3d(f.x * *f.z, f.y * *f.z, *f.z)});
  // sorted by id, for the lookup of every frame
  std::sort(out.begin(), out.end(),
            [](const TaughtPoint& a, const TaughtPoint& b) { return std::pair{a.row, a.col} < std::pair{b.row, b.col}; });
  return out;
}

TaughtCheck check_taught(const std::vector<control::Feature>& features, const std::vector<TaughtPoint>& taught,
                         const Eigen::Isometry3d& world_T_camera, double fx, double fy, const vision::GrownLimit& limit) {
  TaughtCheck c;
  c.off.assign(features.size(), 0);
  const Eigen::Isometry3d camera_T_world = world_T_camera.inverse();
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> residual(features.size(), -1);  // -1: no taught point
  std::vector<double> finite;
  for (std::size_t i = 0; i < features.size(); ++i) {
    const control::Feature& f = features[i];
    const auto it = std::lower_bound(taught.begin(), taught.end(), std::pair{f.row, f.col},
                                     [](const TaughtPoint& t, const std::pair<int, int>& id) {
                                       return std::pair{t.row, t.col} < id;
                                     });
    if (it == taught.end() || it->row != f.row || it->col != f.col) continue;
    ++c.checked;
    const Eigen::Vector3d p = camera_T_world * it->world;
    residual[i] = p.z() > 0 ? std::hypot(fx * (p.x() / p.z() - f.x), fy * (p.y() / p.z() - f.y)) : inf;
    if (std::isfinite(residual[i])) finite.push_back(residual[i]);
  }
  // the limit has no cap: an error that moves every spot alike must loosen it, not empty the law
  c.limit_px = vision::grown_limit_of(std::move(finite), limit, inf);
  for (std::size_t i = 0; i < features.size(); ++i)
    if (residual[i] >= 0 && !(residual[i] <= c.limit_px)) c.off[i] = 1, ++c.kept_out;
  return c;
}

}  // namespace servo
