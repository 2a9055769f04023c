// Kinematics of the arm's chain with KDL (orocos-kdl), the chain built from the RobotModel
// here (not by kdl_parser, which would pull ROS 1 in): forward kinematics of the camera and
// of every link, the geometric Jacobian, and inverse kinematics within the joint limits.
// Poses are of the robot's base (its root link); the camera is the chain's tip.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sim/arm/robot_model.hpp"

namespace sim {

using Matrix6Xd = Eigen::Matrix<double, 6, Eigen::Dynamic>;

class ArmKinematics {
 public:
  explicit ArmKinematics(const RobotModel& model);
  ~ArmKinematics();
  ArmKinematics(const ArmKinematics&) = delete;
  ArmKinematics& operator=(const ArmKinematics&) = delete;

  int dof() const { return dof_; }
  const Eigen::VectorXd& lower() const { return lower_; }
  const Eigen::VectorXd& upper() const { return upper_; }
  const Eigen::VectorXd& max_velocity() const { return velocity_; }

  Eigen::Isometry3d base_T_camera(const Eigen::VectorXd& q) const;
  // base_T_link for the root and then each chain segment's link, in RobotModel::chain order
  std::vector<Eigen::Isometry3d> link_poses(const Eigen::VectorXd& q) const;
  // geometric Jacobian: rows (v, w) of the camera origin, in the base frame
  Matrix6Xd jacobian_base(const Eigen::VectorXd& q) const;
  // the same twist expressed in the camera frame (what the servo commands)
  Matrix6Xd jacobian_camera(const Eigen::VectorXd& q) const;

  // Joint angles within the limits placing the camera at base_T_camera (within 1e-7 m +
  // rad together), the nearest to `seed` of those found from the seed and from seeded restarts;
  // nullopt when none is found, with the reason in *why.
  std::optional<Eigen::VectorXd> inverse(const Eigen::Isometry3d& base_T_camera, const Eigen::VectorXd& seed,
                                         std::string* why = nullptr) const;
  bool within_limits(const Eigen::VectorXd& q, double margin = 0) const;

 private:
  struct Kdl;
  std::unique_ptr<Kdl> kdl_;
  int dof_ = 0;
  Eigen::VectorXd lower_, upper_, velocity_;
};

}  // namespace sim
