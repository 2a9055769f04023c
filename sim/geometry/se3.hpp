// Rigid motions: poses are Eigen::Isometry3d named aTb (pose of frame b in frame a);
// twists are (v, w) in metres/second and radians/second, expressed in the moving frame.
#pragma once

#include <Eigen/Geometry>
#include <optional>

namespace sim {

using Vector6d = Eigen::Matrix<double, 6, 1>;

// Exponential map of se(3): the rigid motion reached after moving with the constant
// body-frame twist (v, w) for one unit of time. Exact (Rodrigues + the V matrix), with
// Taylor series below |w| = 1e-6 so a pure translation stays exact.
Eigen::Isometry3d se3_exp(const Vector6d& twist);

// Inverse of se3_exp (the twist that reaches T in unit time), for tests and error metrics.
Vector6d se3_log(const Eigen::Isometry3d& T);

// The pose a share t (0..1) of the way from a to b along the screw motion between them (a
// constant body twist for the whole way): a at 0, b at 1. Where the camera was between two
// frames, when it moved from one to the other with the twist in force.
Eigen::Isometry3d interpolate(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double t);

// The twist (v, w) of a body expressed in frame B, expressed in frame A instead (a_T_b):
// w_a = R w_b, v_a = R v_b + p x (R w_b).
Vector6d transform_twist(const Eigen::Isometry3d& a_T_b, const Vector6d& twist_b);

// Pose from translation (metres) and intrinsic rotations about X, then Y, then Z (radians):
// T = Trans(x, y, z) * Rx(rx) * Ry(ry) * Rz(rz).
Eigen::Isometry3d pose_from_xyz_rxyz(double x, double y, double z, double rx, double ry, double rz);

// Camera pose looking from `eye` towards `target`, optical frame (x right, y down, z forward),
// with image "up" as close as possible to `up`.
Eigen::Isometry3d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, const Eigen::Vector3d& up);

// Translation distance (m) and rotation angle (rad) between two poses.
double translation_error(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b);
double rotation_error(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b);

// The plane-to-plane task's goal (a projector on the camera, whose spots show the surface and
// nothing more): the plane n . X = d (world, n unit) its spots light from the desired pose.
struct GoalPlane {
  Eigen::Vector3d n_w = Eigen::Vector3d::UnitZ();
  double d = 0;
};
// How far the camera at wTc is from the goal wTd: without a plane, translation_error and
// rotation_error; with one, what the task can see of it: the difference of the camera's
// distances to the plane and the angle between the plane's normal as the two poses see it (a
// translation along the plane or a rotation about its normal leaves both unchanged).
struct GoalError {
  double translation_m = 0, rotation_rad = 0;
};
GoalError goal_error(const Eigen::Isometry3d& wTc, const Eigen::Isometry3d& wTd, const std::optional<GoalPlane>& plane);

}  // namespace sim
