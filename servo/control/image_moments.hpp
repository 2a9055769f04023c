// Image moments of the matched points as visual features (issue 44; the paper's future work,
// after Chaumette, "Image moments: a general and useful set of features for visual servoing",
// IEEE T-RO 20(4), 2004, and Tahri & Chaumette, "Point-based and region-based image moments for
// visual servoing of planar objects", IEEE T-RO 21(6), 2005).
//
// For n points (x_k, y_k), with x_g, y_g their centroid and the centred moments
//   mu_ij = (1/n) sum_k (x_k - x_g)^i (y_k - y_g)^j,   a = mu_20 + mu_02,
// the six features are
//   x_n = a_n x_g,  y_n = a_n y_g,  a_n = Z* sqrt(a* / a)     (Tahri & Chaumette, eq. 30-31)
//   alpha = 1/2 atan2(2 mu_11, mu_20 - mu_02)                  (the orientation, Chaumette 2004)
//   c_1 = ((mu_20 - mu_02)^2 + 4 mu_11^2) / a^2                (invariants to translation,
//   c_2 = ((mu_30 - 3 mu_12)^2 + (3 mu_21 - mu_03)^2) / a^3     rotation and scale in the image)
// a_n, x_n, y_n follow the camera's translation (for a plane parallel to the image, nearly
// decoupled: Tahri & Chaumette), alpha the rotation about the optical axis, c_1 and c_2 the
// rotations about x and y (the role of Tahri & Chaumette's invariants r_1, r_2; these are
// Hu's second- and third-order invariants normalised by the scale, defined for any point set).
//
// The interaction matrix follows exactly from the points' (paper eq. 7) by the chain rule:
//   L_f = sum_k ( df/dx_k L_{x_k} + df/dy_k L_{y_k} ),
//   d mu_ij / d x_k = (i/n) ((x_k - x_g)^(i-1) (y_k - y_g)^j - mu_(i-1)j),
//   d mu_ij / d y_k = (j/n) ((x_k - x_g)^i (y_k - y_g)^(j-1) - mu_i(j-1)),
// with each point's depth in L_{x_k} (the models of interaction_matrix.hpp choose which).
// tests/unit/control/image_moments_test.cpp holds it to finite differences of the projection.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "servo/control/interaction_matrix.hpp"

namespace control {

using Matrix66 = Eigen::Matrix<double, 6, 6>;

// What the law servoes on: every point's (x, y) (the paper), the points' image moments, or the
// surface they lie on with three of the moments (surface_features.hpp).
// points: x, y of every spot; moments: image_moments.hpp; surface, plane: surface_features.hpp
enum class VisualFeatures { kPoints, kMoments, kSurface, kPlane };
std::string to_string(VisualFeatures f);
VisualFeatures parse_visual_features(const std::string& name);  // "points" | "moments" | "surface" | "plane"; throws

struct MomentScale {
  double a_star = 1;  // a of the desired points
  double z_star = 1;  // the depth a_n takes at the desired pose (m)
};

// s = (x_n, y_n, a_n, alpha, c_1, c_2) of the points xy = (x_1, y_1, x_2, y_2, ...).
// Throws std::invalid_argument for fewer than 3 points or points all on one spot (a = 0).
Vector6d moment_features(const Eigen::VectorXd& xy, const MomentScale& scale);
// Its interaction matrix, each point's rows with its depth Z_k (one per point).
Matrix66 moment_interaction_matrix(const Eigen::VectorXd& xy, const Eigen::VectorXd& Z, const MomentScale& scale);
// The same from each point's own two rows (one per point): a spot riding on the camera's
// projector has riding_point_interaction_matrix's, not eq. 7's.
Matrix66 moment_interaction_matrix(const Eigen::VectorXd& xy, const std::vector<Matrix26>& point_rows,
                                   const MomentScale& scale);
// a = mu_20 + mu_02 of the points (MomentScale::a_star of the desired ones)
double moment_area(const Eigen::VectorXd& xy);
// s - s*, with alpha's difference wrapped into (-pi/2, pi/2] (an orientation is defined mod pi)
Vector6d moment_error(const Vector6d& s, const Vector6d& s_star);

}  // namespace control
