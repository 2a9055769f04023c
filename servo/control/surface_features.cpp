#include "servo/control/surface_features.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <stdexcept>
#include <string>

namespace control {

Plane fit_plane(const Eigen::VectorXd& xy, const Eigen::VectorXd& Z) {
  const Eigen::Index n = Z.size();
  if (n < 3 || xy.size() != 2 * n)
    throw std::invalid_argument("surface: " + std::to_string(n) + " points with depths: 3 or more needed");
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (Eigen::Index k = 0; k < n; ++k) {
    if (!(Z[k] > 0)) throw std::invalid_argument("surface: a point without a positive depth");
    mean += Z[k] * Eigen::Vector3d(xy[2 * k], xy[2 * k + 1], 1);
  }
  mean /= static_cast<double>(n);
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (Eigen::Index k = 0; k < n; ++k) {
    const Eigen::Vector3d x = Z[k] * Eigen::Vector3d(xy[2 * k], xy[2 * k + 1], 1) - mean;
    scatter += x * x.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
  // the normal is the direction the points spread least along; a second small spread is a line
  if (!(eig.eigenvalues()[1] > 1e-12 * eig.eigenvalues()[2]))
    throw std::invalid_argument("surface: the points lie on a line");
  Plane p{eig.eigenvectors().col(0).normalized(), 0};
  p.d = p.n.dot(mean);
  if (p.d < 0) p.n = -p.n, p.d = -p.d;  // away from the camera
  return p;
}

Vector6d surface_features(const Eigen::VectorXd& xy, const Eigen::VectorXd& Z, const MomentScale& scale) {
  const Vector6d m = moment_features(xy, scale);
  Vector6d s;
  s << plane_features(fit_plane(xy, Z)), m[0], m[1], m[3];
  return s;
}

Eigen::Vector3d plane_features(const Plane& plane) { return {plane.n.x(), plane.n.y(), plane.d}; }

Eigen::Matrix<double, 3, 6> plane_interaction_matrix(const Plane& plane) {
  const Eigen::Vector3d& n = plane.n;
  Eigen::Matrix<double, 3, 6> L = Eigen::Matrix<double, 3, 6>::Zero();
  // n_dot = [n]_x w: its x and y rows
  L(0, 4) = -n.z(), L(0, 5) = n.y();
  L(1, 3) = n.z(), L(1, 5) = -n.x();
  L.block<1, 3>(2, 0) = -n.transpose();  // d_dot = -n . v
  return L;
}

Matrix66 surface_interaction_matrix(const Eigen::VectorXd& xy, const Eigen::VectorXd& Z, const Plane& plane,
                                    const MomentScale& scale) {
  const Matrix66 M = moment_interaction_matrix(xy, Z, scale);
  Matrix66 L = Matrix66::Zero();
  L.topRows<3>() = plane_interaction_matrix(plane);
  L.row(3) = M.row(0);
  L.row(4) = M.row(1);
  L.row(5) = M.row(3);
  return L;
}

}  // namespace control
