#include "sim/robot/robot.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace sim {

std::string robot_stop_reason(const std::string& event) {
  const std::string suffix = ": robot stopped until RESET";
  if (event.size() >= suffix.size() && event.compare(event.size() - suffix.size(), suffix.size(), suffix) == 0)
    return event.substr(0, event.size() - suffix.size());
  return event;
}

std::string limit_names(std::uint32_t limits) {
  static const char* names[] = {"cartesian_speed",  "joint_velocity", "joint_position", "singularity_slowdown",
                                "singularity_stop", "workspace",      "collision"};
  std::string s;
  for (int i = 0; i < 7; ++i)
    if (limits & (1u << i)) {
      if (!s.empty()) s += '|';
      s += names[i];
    }
  return s;
}

FreeFlyingCamera::FreeFlyingCamera(const Eigen::Isometry3d& world_T_camera, double max_linear_mps,
                                   double max_angular_radps)
    : world_T_camera_(world_T_camera), max_linear_mps_(max_linear_mps), max_angular_radps_(max_angular_radps) {
  if (!(max_linear_mps > 0) || !(max_angular_radps > 0))
    throw std::invalid_argument("FreeFlyingCamera: velocity limits must be positive");
}

Vector6d FreeFlyingCamera::apply_twist(const Vector6d& twist_c, double dt_s) {
  if (!twist_c.allFinite() || !std::isfinite(dt_s) || dt_s < 0)
    throw std::invalid_argument("FreeFlyingCamera::apply_twist: twist and dt must be finite (dt >= 0)");
  Vector6d applied = twist_c;
  for (int i = 0; i < 3; ++i) applied[i] = std::clamp(applied[i], -max_linear_mps_, max_linear_mps_);
  for (int i = 3; i < 6; ++i) applied[i] = std::clamp(applied[i], -max_angular_radps_, max_angular_radps_);
  world_T_camera_ = world_T_camera_ * se3_exp(applied * dt_s);
  // keep the rotation orthonormal over thousands of steps
  world_T_camera_.linear() = Eigen::Quaterniond(world_T_camera_.rotation()).normalized().toRotationMatrix();
  return applied;
}

MotionReport FreeFlyingCamera::move(const Vector6d& twist_c, double dt_s, const Workspace& workspace) {
  MotionReport r;
  FreeFlyingCamera trial = *this;
  // the twist is meant for the camera the controller believes in; the true camera, rigidly
  // attached to it, moves with the same body motion
  const bool exact = camera_T_believed_.matrix().isIdentity(0);
  const Vector6d wanted = exact ? twist_c : transform_twist(camera_T_believed_, twist_c);
  const Vector6d a = trial.apply_twist(wanted, dt_s);
  if (!workspace.contains(trial.world_T_camera().translation())) {
    r.limits = kLimitWorkspace;
    r.event = "a twist would take the camera out of the workspace: robot stopped";
    return r;
  }
  *this = trial;
  r.applied = a;
  if (a != wanted) r.limits = kLimitCartesianSpeed;
  return r;
}

}  // namespace sim
