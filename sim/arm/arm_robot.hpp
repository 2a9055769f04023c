// The arm carrying the camera, as the cell drives it: the servo's camera twist goes
// through the ArmController (damped least squares within the limits) at every physics
// period, the joint velocity motors of the BulletArm follow it, and the camera pose is the
// forward kinematics of the joint angles Bullet reached. A contact stops the arm until the
// next reset, and is reported.
#pragma once

#include <memory>

#include "sim/arm/arm_controller.hpp"
#include "sim/arm/bullet_arm.hpp"
#include "sim/arm/kinematics.hpp"
#include "sim/robot/robot.hpp"

namespace sim {

class ArmRobot final : public Robot {
 public:
  // `objects` (the cell's static world) must outlive the robot. `home`: the IK seed for
  // the first pose asked for (an elbow-up configuration picks that family).
  ArmRobot(std::shared_ptr<const RobotModel> model, const Eigen::Isometry3d& world_T_base, const World& objects,
           std::vector<std::string> object_names, ArmControllerOptions params, Eigen::VectorXd home,
           double physics_period_s = 0.001);

  Eigen::Isometry3d world_T_camera() const override { return world_T_camera_; }
  // the forward kinematics of the believed model (link lengths, joint zeros, hand-eye)
  Eigen::Isometry3d reported_world_T_camera() const override;
  // the controller's model from here on: the true chain with the belief's errors
  void set_belief(const RobotBelief& belief) override;
  void reset(const Eigen::Isometry3d& world_T_camera) override;
  void reset_joints(const Eigen::VectorXd& q);
  // reset() to exactly this pose takes these joint angles (a scenario's desired and
  // initial configurations) instead of solving IK again
  void pin(const Eigen::Isometry3d& world_T_camera, const Eigen::VectorXd& q);
  MotionReport move(const Vector6d& twist_c, double dt_s, const Workspace& workspace) override;
  std::vector<std::string> joint_names() const override { return model_->joint_names(); }
  Eigen::VectorXd joint_positions() const override { return q_; }
  Eigen::VectorXd joint_velocities() const override { return qdot_; }

  // base_T_link for the root and each chain segment (RobotModel order), in the world
  std::vector<Eigen::Isometry3d> world_T_links() const override;
  const RobotModel& model() const { return *model_; }
  const ArmKinematics& kinematics() const { return kin_; }
  const Eigen::Isometry3d& world_T_base() const { return world_T_base_; }
  // the joint angles that put the camera at the pose (nearest `seed`), or why not
  std::optional<Eigen::VectorXd> solve(const Eigen::Isometry3d& world_T_camera, const Eigen::VectorXd& seed,
                                       std::string* why) const;
  const std::optional<std::string>& fault() const { return fault_; }

 private:
  void sync();

  std::shared_ptr<const RobotModel> model_;
  Eigen::Isometry3d world_T_base_;
  ArmKinematics kin_;
  // what the controller believes (null: the truth, kin_)
  std::shared_ptr<const RobotModel> believed_model_;
  std::unique_ptr<ArmKinematics> believed_kin_;
  Eigen::Isometry3d camera_T_believed_ = Eigen::Isometry3d::Identity();
  ArmController controller_;
  BulletArm arm_;
  Eigen::VectorXd home_, q_, qdot_, q_ref_;
  Eigen::Isometry3d world_T_camera_ = Eigen::Isometry3d::Identity();
  std::int64_t period_ns_ = 1000000, carry_ns_ = 0;
  std::optional<std::string> fault_;
  std::vector<std::pair<Eigen::Isometry3d, Eigen::VectorXd>> pinned_;
};

}  // namespace sim
