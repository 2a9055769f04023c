// The cell's robot controller: it takes the servo's camera twist as a real cell's controller
// does (MoveIt Servo, a UR's speedl) and turns it into joint velocities, within the arm's
// limits, keeping the twist's direction whenever it must slow down:
//   1. Cartesian speed: the twist is scaled to the cell's linear and angular limits;
//   2. damped least squares: qdot = J^T (J J^T + l^2 I)^-1 v, the damping growing as the
//      smallest singular value of J falls below `damping_threshold` (Nakamura & Hanafusa);
//   3. singularity: as MoveIt Servo, the motion slows linearly while the condition number
//      of J rises from `slowdown_condition` (17) to `stop_condition` (30) and stops there,
//      but only when the motion heads towards the singularity (leaving it is allowed);
//   4. joint position limits: the step is shortened so no joint enters its margin;
//   5. joint velocity limits: all joints are scaled together by the worst ratio.
// A pure function of the kinematics, the joint state and the command.
#pragma once

#include <cstdint>
#include <string>

#include "sim/arm/kinematics.hpp"
#include "sim/geometry/se3.hpp"
#include "sim/robot/robot.hpp"

namespace sim {

struct ArmControllerOptions {
  double max_linear_mps = 0.5;
  double max_angular_radps = 1.0;
  double damping = 0.05;              // largest damping factor (at sigma_min = 0)
  double damping_threshold = 0.05;    // damping starts below this smallest singular value
  double slowdown_condition = 17;     // MoveIt Servo's lower_singularity_threshold
  double stop_condition = 30;         // MoveIt Servo's hard_stop_singularity_threshold
  double joint_margin_rad = 0.05;     // no joint comes nearer its limit than this (m for prismatic)
};

struct ArmCommand {
  Eigen::VectorXd qdot;                          // joint velocities to hold for dt
  Vector6d twist = Vector6d::Zero();             // the camera twist they make (camera frame)
  double condition = 1;                          // of J
  double scale = 1;                              // overall slow-down applied (0: stopped)
  std::uint32_t limits = 0;                      // RobotLimit bits
};

class ArmController {
 public:
  explicit ArmController(ArmControllerOptions p = {}) : p_(p) {}
  const ArmControllerOptions& params() const { return p_; }

  // twist_c: (v, w) in the camera frame; dt: how long the command will be held.
  ArmCommand step(const ArmKinematics& kin, const Eigen::VectorXd& q, const Vector6d& twist_c, double dt) const;

 private:
  ArmControllerOptions p_;
};

}  // namespace sim
