#include "servo/control/image_moments.hpp"

#include <cmath>
#include <stdexcept>

namespace control {

namespace {

constexpr double kPi = 3.14159265358979323846;

// The moments the features are made of, q = (x_g, y_g, mu_20, mu_11, mu_02, mu_30, mu_21,
// mu_12, mu_03), of points (x_1, y_1, x_2, y_2, ...).
using Vector9d = Eigen::Matrix<double, 9, 1>;
enum Q { kXg, kYg, k20, k11, k02, k30, k21, k12, k03 };

Vector9d moments(const Eigen::VectorXd& xy) {
  const Eigen::Index n = xy.size() / 2;
  if (n < 3 || xy.size() % 2 != 0)
    throw std::invalid_argument("image moments: " + std::to_string(xy.size()) + " coordinates: 3 points or more needed");
  Vector9d q = Vector9d::Zero();
  for (Eigen::Index k = 0; k < n; ++k) q[kXg] += xy[2 * k], q[kYg] += xy[2 * k + 1];
  q[kXg] /= static_cast<double>(n), q[kYg] /= static_cast<double>(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const double u = xy[2 * k] - q[kXg], w = xy[2 * k + 1] - q[kYg];
    q[k20] += u * u, q[k11] += u * w, q[k02] += w * w;
    q[k30] += u * u * u, q[k21] += u * u * w, q[k12] += u * w * w, q[k03] += w * w * w;
  }
  q.tail<7>() /= static_cast<double>(n);
  if (!(q[k20] + q[k02] > 0)) throw std::invalid_argument("image moments: the points are all on one spot");
  return q;
}

// df/dq: each feature's derivative by each moment
Eigen::Matrix<double, 6, 9> feature_jacobian(const Vector9d& q, const MomentScale& s) {
  const double a = q[k20] + q[k02], an = s.z_star * std::sqrt(s.a_star / a), dan = -an / (2 * a);
  const double d = q[k20] - q[k02], D = d * d + 4 * q[k11] * q[k11];
  const double P = q[k30] - 3 * q[k12], Qv = 3 * q[k21] - q[k03], N = P * P + Qv * Qv;
  const double a2 = a * a, a3 = a2 * a, a4 = a3 * a;
  Eigen::Matrix<double, 6, 9> F = Eigen::Matrix<double, 6, 9>::Zero();
  F(0, kXg) = an, F(0, k20) = F(0, k02) = q[kXg] * dan;  // x_n
  F(1, kYg) = an, F(1, k20) = F(1, k02) = q[kYg] * dan;  // y_n
  F(2, k20) = F(2, k02) = dan;                          // a_n
  if (D > 0) F(3, k20) = -q[k11] / D, F(3, k02) = q[k11] / D, F(3, k11) = d / D;  // alpha
  F(4, k20) = 2 * d / a2 - 2 * D / a3, F(4, k02) = -2 * d / a2 - 2 * D / a3, F(4, k11) = 8 * q[k11] / a2;  // c_1
  F(5, k30) = 2 * P / a3, F(5, k12) = -6 * P / a3, F(5, k21) = 6 * Qv / a3, F(5, k03) = -2 * Qv / a3;  // c_2
  F(5, k20) = F(5, k02) = -3 * N / a4;
  return F;
}

}  // namespace

std::string to_string(VisualFeatures f) {
  switch (f) {
    case VisualFeatures::kPoints: return "points";
    case VisualFeatures::kMoments: return "moments";
    case VisualFeatures::kSurface: return "surface";
    case VisualFeatures::kPlane: return "plane";
  }
  return "?";
}

VisualFeatures parse_visual_features(const std::string& name) {
  if (name == "points") return VisualFeatures::kPoints;
  if (name == "moments") return VisualFeatures::kMoments;
  if (name == "surface") return VisualFeatures::kSurface;
  if (name == "plane") return VisualFeatures::kPlane;
  throw std::invalid_argument("visual features '" + printable_name(name) + "': expected points, moments, surface or plane");
}

double moment_area(const Eigen::VectorXd& xy) {
  const Vector9d q = moments(xy);
  return q[k20] + q[k02];
}

Vector6d moment_features(const Eigen::VectorXd& xy, const MomentScale& scale) {
  const Vector9d q = moments(xy);
  const double a = q[k20] + q[k02], an = scale.z_star * std::sqrt(scale.a_star / a);
  const double d = q[k20] - q[k02];
  const double P = q[k30] - 3 * q[k12], Qv = 3 * q[k21] - q[k03];
  Vector6d s;
  s << an * q[kXg], an * q[kYg], an, 0.5 * std::atan2(2 * q[k11], d), (d * d + 4 * q[k11] * q[k11]) / (a * a),
      (P * P + Qv * Qv) / (a * a * a);
  return s;
}

Matrix66 moment_interaction_matrix(const Eigen::VectorXd& xy, const Eigen::VectorXd& Z, const MomentScale& scale) {
  const Eigen::Index n = xy.size() / 2;
  if (Z.size() != n)
    throw std::invalid_argument("image moments: " + std::to_string(Z.size()) + " depths for " + std::to_string(n) + " points");
  std::vector<Matrix26> rows(static_cast<std::size_t>(n));
  for (Eigen::Index k = 0; k < n; ++k) rows[static_cast<std::size_t>(k)] = point_interaction_matrix(xy[2 * k], xy[2 * k + 1], Z[k]);
  return moment_interaction_matrix(xy, rows, scale);
}

Matrix66 moment_interaction_matrix(const Eigen::VectorXd& xy, const std::vector<Matrix26>& point_rows,
                                   const MomentScale& scale) {
  const Vector9d q = moments(xy);
  const Eigen::Index n = xy.size() / 2;
  if (static_cast<Eigen::Index>(point_rows.size()) != n)
    throw std::invalid_argument("image moments: " + std::to_string(point_rows.size()) + " rows for " + std::to_string(n) +
                                " points");
  // L_q = sum_k dq/dx_k L_x,k + dq/dy_k L_y,k
  Eigen::Matrix<double, 9, 6> Lq = Eigen::Matrix<double, 9, 6>::Zero();
  const double in = 1.0 / static_cast<double>(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const double u = xy[2 * k] - q[kXg], w = xy[2 * k + 1] - q[kYg];
    const Matrix26& Lp = point_rows[static_cast<std::size_t>(k)];
    Vector9d dx, dy;
    dx << in, 0, 2 * u * in, w * in, 0, 3 * in * (u * u - q[k20]), 2 * in * (u * w - q[k11]), in * (w * w - q[k02]), 0;
    dy << 0, in, 0, u * in, 2 * w * in, 0, in * (u * u - q[k20]), 2 * in * (u * w - q[k11]), 3 * in * (w * w - q[k02]);
    Lq.noalias() += dx * Lp.row(0) + dy * Lp.row(1);
  }
  return feature_jacobian(q, scale) * Lq;
}

Vector6d moment_error(const Vector6d& s, const Vector6d& s_star) {
  Vector6d e = s - s_star;
  e[3] = std::remainder(e[3], kPi);  // into [-pi/2, pi/2]
  return e;
}

}  // namespace control
