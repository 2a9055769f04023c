#include "servo/calibration/camera_intrinsics.hpp"

namespace calibration {

Eigen::Vector2d normalise(const CameraIntrinsics& k, const Eigen::Vector2d& uv) {
  const Eigen::Vector2d xd((uv.x() - k.cx) / k.fx, (uv.y() - k.cy) / k.fy);
  const auto& d = k.distortion;
  if (d[0] == 0 && d[1] == 0 && d[2] == 0 && d[3] == 0 && d[4] == 0) return xd;
  // fixed-point inversion of the distortion (as OpenCV's undistortPoints), converges for
  // lens-like distortion in a few iterations
  Eigen::Vector2d x = xd;
  for (int it = 0; it < 30; ++it) {
    const double r2 = x.squaredNorm();
    const double radial = 1 + d[0] * r2 + d[1] * r2 * r2 + d[4] * r2 * r2 * r2;
    const Eigen::Vector2d tangential(2 * d[2] * x.x() * x.y() + d[3] * (r2 + 2 * x.x() * x.x()),
                                     d[2] * (r2 + 2 * x.y() * x.y()) + 2 * d[3] * x.x() * x.y());
    const Eigen::Vector2d next = (xd - tangential) / radial;
    if ((next - x).squaredNorm() < 1e-26) return next;
    x = next;
  }
  return x;
}

}  // namespace calibration
