#include "servo/control/triangulation.hpp"

namespace control {

std::optional<double> triangulate_depth(const Eigen::Vector2d& xy, int row, int col, const calibration::ProjectorModel& projector,
                                        const Eigen::Isometry3d& world_T_camera) {
  const Eigen::Isometry3d c_T_p = projector.camera_T_projector(world_T_camera);
  // camera ray: origin 0, direction a; projector ray: origin o, direction b (camera frame)
  const Eigen::Vector3d a(xy.x(), xy.y(), 1.0);
  const Eigen::Vector3d o = c_T_p.translation();
  const Eigen::Vector3d b = c_T_p.linear() * projector.spot_ray(row, col);
  // minimise |s a - (o + t b)|: the normal equations of the two ray parameters
  const double aa = a.dot(a), ab = a.dot(b), bb = b.dot(b), ao = a.dot(o), bo = b.dot(o);
  const double det = aa * bb - ab * ab;
  if (det < 1e-12 * aa * bb) return std::nullopt;  // parallel rays: no baseline to triangulate
  const double s = (ao * bb - ab * bo) / det;
  const double t = (ab * ao - aa * bo) / det;
  if (s <= 0 || t <= 0) return std::nullopt;
  const Eigen::Vector3d midpoint = 0.5 * (s * a + o + t * b);
  if (midpoint.z() <= 0) return std::nullopt;
  return midpoint.z();
}

}  // namespace control
