#include "sim/render/camera_model.hpp"

namespace sim {

CameraModel::CameraModel(const Intrinsics& intrinsics, const std::array<double, 5>& distortion)
    : k_(intrinsics), d_(distortion) {
  pixel_rays_.resize(static_cast<std::size_t>(k_.width) * k_.height * 2);
  std::size_t i = 0;
  for (int v = 0; v < k_.height; ++v)
    for (int u = 0; u < k_.width; ++u) {
      const Eigen::Vector2d xn = pixel_to_normalised({u, v});
      pixel_rays_[i++] = static_cast<float>(xn.x());
      pixel_rays_[i++] = static_cast<float>(xn.y());
    }
}

bool CameraModel::has_distortion() const {
  for (double c : d_)
    if (c != 0.0) return true;
  return false;
}

Eigen::Vector2d CameraModel::distort_to_pixel(const Eigen::Vector2d& xn) const {
  const double x = xn.x(), y = xn.y();
  const double r2 = x * x + y * y;
  const double radial = 1 + d_[0] * r2 + d_[1] * r2 * r2 + d_[4] * r2 * r2 * r2;
  const double xd = x * radial + 2 * d_[2] * x * y + d_[3] * (r2 + 2 * x * x);
  const double yd = y * radial + d_[2] * (r2 + 2 * y * y) + 2 * d_[3] * x * y;
  return {k_.fx * xd + k_.cx, k_.fy * yd + k_.cy};
}

Eigen::Vector2d CameraModel::pixel_to_normalised(const Eigen::Vector2d& uv) const {
  const double xd = (uv.x() - k_.cx) / k_.fx;
  const double yd = (uv.y() - k_.cy) / k_.fy;
  if (!has_distortion()) return {xd, yd};
  // Newton iterations on the forward model (converges in a few steps for lens-like distortion)
  Eigen::Vector2d x(xd, yd);
  for (int it = 0; it < 20; ++it) {
    const Eigen::Vector2d f = distort_to_pixel(x);
    const Eigen::Vector2d r((f.x() - k_.cx) / k_.fx - xd, (f.y() - k_.cy) / k_.fy - yd);
    if (r.squaredNorm() < 1e-24) break;
    const double h = 1e-7;
    Eigen::Matrix2d J;
    for (int c = 0; c < 2; ++c) {
      Eigen::Vector2d xp = x;
      xp[c] += h;
      const Eigen::Vector2d fp = distort_to_pixel(xp);
      J(0, c) = ((fp.x() - f.x()) / k_.fx) / h;
      J(1, c) = ((fp.y() - f.y()) / k_.fy) / h;
    }
    x -= J.inverse() * r;
  }
  return x;
}

}  // namespace sim
