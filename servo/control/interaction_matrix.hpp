// The interaction matrix of image points (paper eqs. 7-8, after Espiau-Chaumette-Rives):
// the velocity of a normalised image point under a camera twist v = (vx vy vz wx wy wz),
//   x_dot = L_x v,  L_x = [ -1/Z   0   x/Z   xy   -(1+x^2)   y ]
//                         [  0   -1/Z  y/Z  1+y^2   -xy     -x ]
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace control {

using Matrix26 = Eigen::Matrix<double, 2, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

Matrix26 point_interaction_matrix(double x, double y, double Z);

// A spot cast by a projector riding on the camera (issue 44) is no fixed point of the world: it
// lies on a ray fixed in the camera frame, X = o + mu b, where the ray meets the surface, and
// slides along the ray as the camera moves. With the surface's plane n . X = d there (camera
// frame), n_dot = n x w and d_dot = -n . v (surface_features.hpp), so n . X_dot = d_dot -
// n_dot . X gives mu_dot = -(n . v + (X x n) . w) / (n . b), and with X = Z (x, y, 1):
//   L = -(1/Z) [1 0 -x; 0 1 -y] b [n^T, (X x n)^T] / (n . b)
// Rank 1: the spot moves along its epipolar line, and only the plane's three degrees of freedom
// (its distance and two tilts) move it. Exact on a plane (tests/unit/control: finite
// differences); on a curved surface n is the fitted plane's, not the local normal.
Matrix26 riding_point_interaction_matrix(double x, double y, double Z, const Eigen::Vector3d& b, const Eigen::Vector3d& n);

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
