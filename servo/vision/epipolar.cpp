#include "servo/vision/epipolar.hpp"

#include <algorithm>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
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
      rays_.push_back({line, b, b.dot(b), b.dot(origin_)});
    }
}

EpipolarGeometry::EpipolarGeometry(const calibration::CameraIntrinsics& camera, const FittedEpipolarLines& lines,
                                   int rows, int cols, double tolerance_px)
    : camera_(camera), origin_(Eigen::Vector3d::Zero()), rows_(rows), cols_(cols), tolerance_px_(tolerance_px),
      front_check_(false) {
  const double pixels = 0.5 * (camera.fx + camera.fy);
  rays_.reserve(static_cast<std::size_t>(rows_) * cols_);
  trusted_.reserve(static_cast<std::size_t>(rows_) * cols_);
  for (int r = 0; r < rows_; ++r)
    for (int c = 0; c < cols_; ++c) {
      const Eigen::Vector2d grid(c, r);
      Eigen::Vector3d line = lines.fundamental() * grid.homogeneous();
      const double n = std::hypot(line.x(), line.y());
      // (as a ray through the camera's centre: no line, nothing passes)
      line = n > 1e-12 && line.allFinite() ? Eigen::Vector3d(line * pixels / n) : Eigen::Vector3d(0, 0, 1e18);
      rays_.push_back({line, Eigen::Vector3d::Zero()});
      trusted_.push_back(lines.spans(grid) ? 1 : 0);
    }
}

Eigen::Vector2d EpipolarGeometry::normalise(double u, double v) const { return calibration::normalise(camera_, {u, v}); }

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

double cross(const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

// The convex hull of points, counter-clockwise (Andrew's monotone chain); fewer than 3 distinct
// points, or all on a line: empty.
std::vector<Eigen::Vector2d> convex_hull(std::vector<Eigen::Vector2d> pts) {
  const auto before = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  };
  std::sort(pts.begin(), pts.end(), before);
  pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
  if (pts.size() < 3) return {};
  std::vector<Eigen::Vector2d> h(2 * pts.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {  // the lower hull
    while (k >= 2 && cross(h[k - 2], h[k - 1], pts[i]) <= 0) --k;
    h[k++] = pts[i];
  }
  for (std::size_t i = pts.size() - 1, lower = k + 1; i > 0; --i) {  // the upper
    while (k >= lower && cross(h[k - 2], h[k - 1], pts[i - 1]) <= 0) --k;
    h[k++] = pts[i - 1];
  }
  h.resize(k - 1);
  if (h.size() < 3) return {};
  return h;
}

}  // namespace

bool FittedEpipolarLines::spans(const Eigen::Vector2d& grid) const {
  if (hull_.empty()) return false;
  for (std::size_t i = 0; i < hull_.size(); ++i)
    if (cross(hull_[i], hull_[(i + 1) % hull_.size()], grid) < 0) return false;
  return true;
}

FittedEpipolarLines::FittedEpipolarLines(const std::vector<Eigen::Vector2d>& xy, const std::vector<Eigen::Vector2d>& grid,
                                         double pixels_per_unit, double tolerance_px, bool rank2)
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
    if (pass == 2) {  // (the last fit's weights would serve nothing)
      if (rank2) {  // lines to name new spots by: where they are extrapolated (spans())
        refine_rank2(xy, grid, w);
        std::vector<Eigen::Vector2d> used;
        for (std::size_t k = 0; k < grid.size(); ++k)
          if (w[k] > 0) used.push_back(grid[k]);
        hull_ = convex_hull(std::move(used));
      }
      break;
    }
    for (std::size_t k = 0; k < xy.size(); ++k) {
      const Eigen::Vector3d line = f_ * grid[k].homogeneous();
      const double g2 = line.head<2>().squaredNorm();
      const bool near = g2 > 0 && std::abs(line.dot(xy[k].homogeneous())) / std::sqrt(g2) * pixels_ <= tolerance_px;
      w[k] = near ? 1.0 / g2 : 0.0;
    }
  }
}

// F = U diag(1, s, 0) V' from the linear fit's SVD, refined by Levenberg-Marquardt over small
// rotations of U and V and over s (7 degrees of freedom: a fundamental matrix's), minimising the
// pixel distances of the spots the last fit used to their lines; numeric derivatives. It stops
// when an iteration gains under 0.01 % of the squared distances (their RMS then moves by under
// 0.005 %), after 20 at most: on a planar scene F is not determined (a homography fits every
// spot) and the fit would crawl along its valley, 6 ms a frame on the plane for lines no nearer
// their spots.
void FittedEpipolarLines::refine_rank2(const std::vector<Eigen::Vector2d>& xy, const std::vector<Eigen::Vector2d>& grid,
                                       const std::vector<double>& w) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(f_, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d u = svd.matrixU(), v = svd.matrixV();
  if (u.determinant() < 0) u = -u;
  if (v.determinant() < 0) v = -v;
  const Eigen::Vector3d sv = svd.singularValues();
  if (!(sv[0] > 0)) return;
  double s = sv[1] / sv[0];
  std::vector<int> in;
  for (std::size_t k = 0; k < xy.size(); ++k)
    if (w[k] > 0) in.push_back(static_cast<int>(k));
  if (in.size() < 9) return;
  const auto make = [](const Eigen::Matrix3d& uu, const Eigen::Matrix3d& vv, double ss) {
    return Eigen::Matrix3d(uu * Eigen::Vector3d(1, ss, 0).asDiagonal() * vv.transpose());
  };
  const auto rot = [](const Eigen::Vector3d& om) {
    const double a = om.norm();
    return a < 1e-15 ? Eigen::Matrix3d(Eigen::Matrix3d::Identity())
                     : Eigen::Matrix3d(Eigen::AngleAxisd(a, om / a).toRotationMatrix());
  };
  const auto residuals = [&](const Eigen::Matrix3d& f) {
    Eigen::VectorXd r(static_cast<Eigen::Index>(in.size()));
    for (std::size_t i = 0; i < in.size(); ++i) {
      const Eigen::Vector3d line = f * grid[in[i]].homogeneous();
      r[static_cast<Eigen::Index>(i)] = line.dot(xy[in[i]].homogeneous()) / line.head<2>().norm() * pixels_;
    }
    return r;
  };
  Eigen::VectorXd r = residuals(make(u, v, s));
  double cost = r.squaredNorm(), lambda = 1e-3;
  for (int it = 0; it < 20; ++it) {
    const auto params = [&](const Eigen::Matrix<double, 7, 1>& d) {
      return make(u * rot(d.head<3>()), v * rot(d.segment<3>(3)), s + d[6]);
    };
    Eigen::MatrixXd jac(r.size(), 7);
    for (int j = 0; j < 7; ++j) {
      Eigen::Matrix<double, 7, 1> d = Eigen::Matrix<double, 7, 1>::Zero();
      const double h = 1e-7;
      d[j] = h;
      jac.col(j) = (residuals(params(d)) - r) / h;
    }
    const Eigen::Matrix<double, 7, 7> jtj = jac.transpose() * jac;
    const Eigen::Matrix<double, 7, 1> g = jac.transpose() * r;
    bool better = false;
    for (int tries = 0; tries < 10 && !better; ++tries) {
      Eigen::Matrix<double, 7, 7> a = jtj;
      a.diagonal() *= 1 + lambda;
      const Eigen::Matrix<double, 7, 1> d = -a.ldlt().solve(g);
      const Eigen::Matrix3d f = params(d);
      const Eigen::VectorXd rn = residuals(f);
      if (rn.allFinite() && rn.squaredNorm() < cost) {
        u = u * rot(d.head<3>()), v = v * rot(d.segment<3>(3)), s += d[6];
        r = rn;
        const double gain = cost - rn.squaredNorm();
        cost = rn.squaredNorm();
        lambda *= 0.3;
        better = true;
        if (gain < 1e-4 * cost) it = 20;
      } else {
        lambda *= 10;
      }
    }
    if (!better) break;
  }
  f_ = make(u, v, s);
}

double FittedEpipolarLines::residual_px(const Eigen::Vector2d& xy, const Eigen::Vector2d& grid) const {
  if (!fitted_) return 0;
  const Eigen::Vector3d line = f_ * grid.homogeneous();
  const double g = line.head<2>().norm();
  if (!(g > 0)) return std::numeric_limits<double>::infinity();
  return std::abs(line.dot(xy.homogeneous())) / g * pixels_;
}

}  // namespace vision
