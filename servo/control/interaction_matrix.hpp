// The interaction matrix of image points (paper eqs. 7-8, after Espiau-Chaumette-Rives):
// the velocity of a normalised image point under a camera twist v = (vx vy vz wx wy wz),
//   x_dot = L_x v,  L_x = [ -1/Z   0   x/Z   xy   -(1+x^2)   y ]
//                         [  0   -1/Z  y/Z  1+y^2   -xy     -x ]
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace control {

using Matrix26 = Eigen::Matrix<double, 2, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

Matrix26 point_interaction_matrix(double x, double y, double Z);

// Stacked for k points (eq. 8): 2k x 6. xy holds (x1, y1, x2, y2, ...), Z one depth per point.
Eigen::MatrixXd stacked_interaction_matrix(const Eigen::VectorXd& xy, const Eigen::VectorXd& Z);

// The models of L-hat the paper compares (§6), plus their mean:
//   kDesiredConstantDepth  L(s*, Z-hat): every depth set to one value (the paper's experiments)
//   kDesired               L(s*, Z*): the desired features with their true depths
//   kCurrent               L(s, Z): the current features and depths, every iteration
//   kMean                  (L(s, Z) + L(s*, Z*)) / 2
enum class InteractionModel { kDesiredConstantDepth, kDesired, kCurrent, kMean };

std::string to_string(InteractionModel m);
// A name as an error message shows it: at most 40 characters, control and non-ASCII bytes as
// '?' (the parsers below echo what they were given).
std::string printable_name(const std::string& name);
// Accepts the names above in kebab case: desired-constant-depth, desired, current, mean.
// Throws std::invalid_argument naming the accepted values.
InteractionModel parse_interaction_model(const std::string& name);

}  // namespace control
