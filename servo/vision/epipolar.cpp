#include "servo/vision/epipolar.hpp"

#include <cmath>
#include <limits>

namespace vision {

EpipolarGeometry::EpipolarGeometry(const calibration::CameraIntrinsics& camera, const calibration::ProjectorModel& projector,
                                   const Eigen::Isometry3d& world_T_camera, double tolerance_px)
    : camera_(camera), rows_(projector.rows), cols_(projector.cols), tolerance_px_(tolerance_px) {
  const Eigen::Isometry3d c_T_p = projector.camera_T_projector(world_T_camera);
  origin_ = c_T_p.translation();
  const double pixels = 0.5 * (camera.fx + camera.fy);
  rays_.reserve(static_cast<std::size_t>(rows_) * cols_);
  for (int r = 0; r < rows_; ++r)
    for (int c = 0; c < cols_; ++c) {
      const Eigen::Vector3d b = c_T_p.linear() * projector.spot_ray(r, c);
      Eigen::Vector3d line = origin_.cross(b);
      const double n = std::hypot(line.x(), line.y());
      // a ray through the camera's centre has no line: nothing can be checked, nothing passes
      line = n > 1e-12 ? Eigen::Vector3d(line * pixels / n) : Eigen::Vector3d(0, 0, 1e18);
      rays_.push_back({line, b});
    }
}

Eigen::Vector2d EpipolarGeometry::normalise(double u, double v) const { return calibration::normalise(camera_, {u, v}); }

double EpipolarGeometry::residual_px(const Eigen::Vector2d& xy, const pattern::SpotId& id) const {
  constexpr double kNever = std::numeric_limits<double>::infinity();
  if (id.row < 0 || id.col < 0 || id.row >= rows_ || id.col >= cols_) return kNever;
  const Ray& ray = rays_[static_cast<std::size_t>(id.row) * cols_ + id.col];
  const Eigen::Vector3d a(xy.x(), xy.y(), 1.0);
  const double residual = std::abs(ray.line.dot(a));
  if (!(residual <= tolerance_px_)) return residual;  // NaN-safe: only a passing point is triangulated
  // the two rays s a and o + t b must meet (nearly) in front of both devices
  const Eigen::Vector3d& b = ray.direction;
  const double aa = a.dot(a), ab = a.dot(b), bb = b.dot(b), ao = a.dot(origin_), bo = b.dot(origin_);
  const double det = aa * bb - ab * ab;
  if (det < 1e-12 * aa * bb) return kNever;
  const double s = (ao * bb - ab * bo) / det, t = (ab * ao - aa * bo) / det;
  return s > 0 && t > 0 ? residual : kNever;
}

}  // namespace vision
