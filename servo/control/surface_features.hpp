// The surface as a feature (issue 44, after the plane-to-plane task of Pagès, Collewet,
// Chaumette & Salvi, IROS 2004 and IEEE T-RO 22(5), 2006): the plane fitted to the triangulated
// spots, its normal and distance servoed directly, and the image moments of the points for the
// three degrees of freedom a plane leaves free (the translation along it and the rotation
// about its normal).
//
// The plane n . X = d in the camera frame (n unit, pointing away from the camera, d > 0) is a
// fixed plane of the world seen from a moving camera: under the twist v = (v, w),
//   n_dot = -w x n = [n]_x w,      d_dot = -n . v
// (every point X of it moves by -v - w x X). The features
//   s = (n_x, n_y, d, x_n, y_n, alpha)
// take n_x, n_y (n_z follows from them), d, and image_moments.hpp's x_n, y_n and alpha, with
// their rows of its interaction matrix. Exact for a plane; on a curved surface the fit is the
// plane nearest the spots. tests/unit/control/image_moments_test.cpp holds it to finite
// differences of the projection.
#pragma once

#include <Eigen/Core>

#include "servo/control/image_moments.hpp"

namespace control {

struct Plane {
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
  double d = 1;
};

// The least-squares plane through the points Z_k (x_k, y_k, 1). Throws std::invalid_argument
// for fewer than 3 points, a non-positive depth, or points on a line (no plane).
Plane fit_plane(const Eigen::VectorXd& xy, const Eigen::VectorXd& Z);

// The plane-to-plane task alone (the follow-up's, for an emitter on the camera, whose spots show
// the plane and nothing else): s = (n_x, n_y, d), the first three rows of the surface's. Three
// degrees of freedom; the law's pseudo-inverse leaves the other three still.
Eigen::Vector3d plane_features(const Plane& plane);
Eigen::Matrix<double, 3, 6> plane_interaction_matrix(const Plane& plane);

Vector6d surface_features(const Eigen::VectorXd& xy, const Eigen::VectorXd& Z, const MomentScale& scale);
// with the plane's rows from `plane` and the moments' from the points with depths Z
Matrix66 surface_interaction_matrix(const Eigen::VectorXd& xy, const Eigen::VectorXd& Z, const Plane& plane,
                                    const MomentScale& scale);

}  // namespace control
