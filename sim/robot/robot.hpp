// What carries the camera. The controller commands a camera-frame twist; a robot turns it
// into motion within its limits. First a free-flying camera; an arm later, behind the
// same interface.
#pragma once

#include <Eigen/Geometry>

#include "sim/geometry/se3.hpp"

namespace sim {

class Robot {
 public:
  virtual ~Robot() = default;
  virtual Eigen::Isometry3d world_T_camera() const = 0;
  virtual void reset(const Eigen::Isometry3d& world_T_camera) = 0;
  // Moves for dt seconds under the twist (v, w) expressed in the camera frame. Returns the
  // twist actually applied (after the robot's limits).
  virtual Vector6d apply_twist(const Vector6d& twist_c, double dt_s) = 0;
};

// A camera that moves exactly as commanded, each axis clamped to its velocity limit:
// T <- T * exp(dt * twist), the exact exponential map of the constant body twist.
class FreeFlyingCamera final : public Robot {
 public:
  FreeFlyingCamera(const Eigen::Isometry3d& world_T_camera, double max_linear_mps, double max_angular_radps);
  Eigen::Isometry3d world_T_camera() const override { return world_T_camera_; }
  void reset(const Eigen::Isometry3d& world_T_camera) override { world_T_camera_ = world_T_camera; }
  Vector6d apply_twist(const Vector6d& twist_c, double dt_s) override;

 private:
  Eigen::Isometry3d world_T_camera_;
  double max_linear_mps_;
  double max_angular_radps_;
};

}  // namespace sim
