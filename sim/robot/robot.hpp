// What carries the camera. The controller commands a camera-frame twist; a robot turns it
// into motion within its limits: a free-flying camera (the paper's idealisation), or an
// arm from URDF simulated by Bullet (sim/arm), behind the same interface.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "sim/geometry/se3.hpp"
#include "sim/geometry/workspace.hpp"

namespace sim {

// Why a motion was limited (bits; in rt/sim/status and the trace).
enum RobotLimit : std::uint32_t {
  kLimitCartesianSpeed = 1u << 0,       // the cell's linear or angular speed limit
  kLimitJointVelocity = 1u << 1,        // a joint's velocity limit (all joints slowed together)
  kLimitJointPosition = 1u << 2,        // a joint reached its position margin
  kLimitSingularitySlowdown = 1u << 3,  // condition number between the two thresholds
  kLimitSingularityStop = 1u << 4,      // condition number at the stop threshold
  kLimitWorkspace = 1u << 5,            // the camera would leave the workspace
  kLimitCollision = 1u << 6,            // a contact stopped the arm
};
// "joint_velocity|singularity_slowdown"; "" when none.
std::string limit_names(std::uint32_t limits);

// What one motion did.
struct MotionReport {
  Vector6d applied = Vector6d::Zero();  // the camera twist made (camera frame), averaged
  std::uint32_t limits = 0;             // RobotLimit bits
  std::string event;                    // non-empty when the robot stopped by itself: why
};

// The robot stopped by itself and holds still until a reset (a collision, a fault). A motion
// refused at the workspace border is not: the step is not made, and the next twist may move it.
inline bool stopped_until_reset(const MotionReport& r) { return !r.event.empty() && !(r.limits & kLimitWorkspace); }
// "collision: link 'A' touches object 'B' (0.4 mm deep)" from such a motion's event line (the
// line tells a service's client what to do, "... until RESET"; a session that ends needs not)
std::string robot_stop_reason(const std::string& event);

// What the cell's controller believes of the robot when its calibration is off (issue 13):
// the camera on the flange (hand-eye) and, for an arm, each joint origin's offset and each
// joint's zero. The robot moves by the truth; it executes a twist for the camera it believes
// in and reports the pose of that camera.
struct RobotBelief {
  Eigen::Isometry3d camera_T_believed = Eigen::Isometry3d::Identity();  // hand-eye error
  std::vector<double> link_scale;        // per chain segment (arm); empty: exact
  std::vector<double> joint_offset_rad;  // per chain segment (arm); empty: exact
  bool exact() const { return camera_T_believed.matrix().isIdentity(0) && link_scale.empty() && joint_offset_rad.empty(); }
};

class Robot {
 public:
  virtual ~Robot() = default;
  virtual Eigen::Isometry3d world_T_camera() const = 0;
  // the camera pose the robot reports (tf): the true one unless set_belief said otherwise
  virtual Eigen::Isometry3d reported_world_T_camera() const = 0;
  virtual void set_belief(const RobotBelief& belief) = 0;
  // Places the camera at the pose. Throws std::invalid_argument (one line) when the robot
  // cannot be there (out of reach, in collision).
  virtual void reset(const Eigen::Isometry3d& world_T_camera) = 0;
  // Moves for dt seconds under the twist (v, w) expressed in the camera frame, keeping the
  // camera inside the workspace (the motion stops at its border).
  virtual MotionReport move(const Vector6d& twist_c, double dt_s, const Workspace& workspace) = 0;
  // joint state (empty for a robot without joints)
  virtual std::vector<std::string> joint_names() const { return {}; }
  virtual Eigen::VectorXd joint_positions() const { return {}; }
  virtual Eigen::VectorXd joint_velocities() const { return {}; }
  // where its links are, for drawing them (empty for a robot the camera never sees)
  virtual std::vector<Eigen::Isometry3d> world_T_links() const { return {}; }
};

// A camera that moves exactly as commanded, each axis clamped to its velocity limit:
// T <- T * exp(dt * twist), the exact exponential map of the constant body twist.
class FreeFlyingCamera final : public Robot {
 public:
  FreeFlyingCamera(const Eigen::Isometry3d& world_T_camera, double max_linear_mps, double max_angular_radps);
  Eigen::Isometry3d world_T_camera() const override { return world_T_camera_; }
  Eigen::Isometry3d reported_world_T_camera() const override {
    return camera_T_believed_.matrix().isIdentity(0) ? world_T_camera_ : world_T_camera_ * camera_T_believed_;
  }
  // a free-flying camera has no joints: only the hand-eye part applies
  void set_belief(const RobotBelief& belief) override { camera_T_believed_ = belief.camera_T_believed; }
  void reset(const Eigen::Isometry3d& world_T_camera) override { world_T_camera_ = world_T_camera; }
  MotionReport move(const Vector6d& twist_c, double dt_s, const Workspace& workspace) override;
  // the motion without a workspace; returns the twist applied
  Vector6d apply_twist(const Vector6d& twist_c, double dt_s);

 private:
  Eigen::Isometry3d world_T_camera_;
  Eigen::Isometry3d camera_T_believed_ = Eigen::Isometry3d::Identity();
  double max_linear_mps_;
  double max_angular_radps_;
};

}  // namespace sim
