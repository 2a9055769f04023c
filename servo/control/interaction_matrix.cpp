#include "servo/control/interaction_matrix.hpp"

#include <stdexcept>

namespace control {

Matrix26 point_interaction_matrix(double x, double y, double Z) {
  const double iz = 1.0 / Z;
  Matrix26 L;
  L << -iz, 0, x * iz, x * y, -(1 + x * x), y,  //
      0, -iz, y * iz, 1 + y * y, -x * y, -x;
  return L;
}

Matrix26 riding_point_interaction_matrix(double x, double y, double Z, const Eigen::Vector3d& b, const Eigen::Vector3d& n) {
  const Eigen::Vector3d X = Z * Eigen::Vector3d(x, y, 1);
  Eigen::Matrix<double, 2, 3> P;
  P << 1, 0, -x, 0, 1, -y;
  Eigen::Matrix<double, 1, 6> mu_dot;  // times -(n . b)
  mu_dot << n.transpose(), X.cross(n).transpose();
  return -(P * b) * mu_dot / (Z * n.dot(b));
}

Eigen::MatrixXd stacked_interaction_matrix(const Eigen::VectorXd& xy, const Eigen::VectorXd& Z) {
  if (xy.size() != 2 * Z.size())
    throw std::invalid_argument("stacked_interaction_matrix: " + std::to_string(xy.size()) + " coordinates for " +
                                std::to_string(Z.size()) + " depths");
  Eigen::MatrixXd L(xy.size(), 6);
  for (Eigen::Index i = 0; i < Z.size(); ++i) L.block<2, 6>(2 * i, 0) = point_interaction_matrix(xy[2 * i], xy[2 * i + 1], Z[i]);
  return L;
}

std::string to_string(InteractionModel m) {
  switch (m) {
    case InteractionModel::kDesiredConstantDepth: return "desired-constant-depth";
    case InteractionModel::kDesired: return "desired";
    case InteractionModel::kCurrent: return "current";
    case InteractionModel::kMean: return "mean";
  }
  return "?";
}

std::string printable_name(const std::string& name) {
  std::string shown;
  for (char c : name.substr(0, 40)) shown += (c >= 0x20 && c < 0x7f) ? c : '?';
  return shown;
}

InteractionModel parse_interaction_model(const std::string& name) {
  for (auto m : {InteractionModel::kDesiredConstantDepth, InteractionModel::kDesired, InteractionModel::kCurrent,
                 InteractionModel::kMean})
    if (to_string(m) == name) return m;
  throw std::invalid_argument("interaction model '" + printable_name(name) +
                              "': expected desired-constant-depth, desired, current or mean");
}

}  // namespace control
