#include "servo/vision/epipolar.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <optional>

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

namespace {

// Hartley's normalisation: the points' centroid to the origin, their mean distance to sqrt 2
// (the linear fit's matrix is then well conditioned).
Eigen::Matrix3d normalising(const std::vector<Eigen::Vector2d>& q) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& x : q) mean += x;
  mean /= static_cast<double>(q.size());
  double spread = 0;
  for (const auto& x : q) spread += (x - mean).norm();
  spread /= static_cast<double>(q.size());
  const double s = spread > 0 ? std::sqrt(2.0) / spread : 1.0;
  Eigen::Matrix3d t;
  t << s, 0, -s * mean.x(), 0, s, -s * mean.y(), 0, 0, 1;
  return t;
}

// The F minimising sum w (x' F p)^2 over unit-norm F, in normalised coordinates.
std::optional<Eigen::Matrix3d> weighted_fit(const std::vector<Eigen::Vector3d>& x, const std::vector<Eigen::Vector3d>& p,
                                            const std::vector<double>& w) {
  Eigen::Matrix<double, 9, 9> m = Eigen::Matrix<double, 9, 9>::Zero();
  int used = 0;
  for (std::size_t k = 0; k < x.size(); ++k) {
    if (!(w[k] > 0)) continue;
    Eigen::Matrix<double, 9, 1> a;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) a[3 * i + j] = x[k][i] * p[k][j];
    m.noalias() += w[k] * a * a.transpose();
    ++used;
  }
  if (used < 9) return std::nullopt;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> eig(m);
  if (eig.info() != Eigen::Success) return std::nullopt;
  const Eigen::Matrix<double, 9, 1> f = eig.eigenvectors().col(0);  // the smallest eigenvalue's
  Eigen::Matrix3d fm;
  fm << f[0], f[1], f[2], f[3], f[4], f[5], f[6], f[7], f[8];
  return fm;
}

}  // namespace

FittedEpipolarLines::FittedEpipolarLines(const std::vector<Eigen::Vector2d>& xy, const std::vector<Eigen::Vector2d>& grid,
                                         double pixels_per_unit, double tolerance_px)
    : pixels_(pixels_per_unit) {
  if (xy.size() != grid.size() || xy.size() < 9) return;
  const Eigen::Matrix3d tx = normalising(xy), tp = normalising(grid);
  std::vector<Eigen::Vector3d> x, p;
  for (std::size_t k = 0; k < xy.size(); ++k) {
    x.push_back(tx * xy[k].homogeneous());
    p.push_back(tp * grid[k].homogeneous());
  }
  std::vector<double> w(xy.size(), 1.0);
  // a first fit to every spot, then two to those within the tolerance of it, each weighted so
  // that its term is its distance to its line (the algebraic x' F p is that distance times the
  // line's gradient): a spill or a misplaced centroid pulls the first fit little, none after
  for (int pass = 0; pass < 3; ++pass) {
    const std::optional<Eigen::Matrix3d> f = weighted_fit(x, p, w);
    if (!f || !f->allFinite()) break;
    f_ = tx.transpose() * *f * tp;
    fitted_ = true;
    if (pass == 2) break;  // the last fit's weights would serve nothing
    for (std::size_t k = 0; k < xy.size(); ++k) {
      const Eigen::Vector3d line = f_ * grid[k].homogeneous();
      const double g2 = line.head<2>().squaredNorm();
      const bool near = g2 > 0 && std::abs(line.dot(xy[k].homogeneous())) / std::sqrt(g2) * pixels_ <= tolerance_px;
      w[k] = near ? 1.0 / g2 : 0.0;
    }
  }
}

double FittedEpipolarLines::residual_px(const Eigen::Vector2d& xy, const Eigen::Vector2d& grid) const {
  if (!fitted_) return 0;
  const Eigen::Vector3d line = f_ * grid.homogeneous();
  const double g = line.head<2>().norm();
  if (!(g > 0)) return std::numeric_limits<double>::infinity();
  return std::abs(line.dot(xy.homogeneous())) / g * pixels_;
}

}  // namespace vision
