#include "sim/arm/arm_robot.hpp"

#include <cmath>
#include <stdexcept>

namespace sim {

ArmRobot::ArmRobot(std::shared_ptr<const RobotModel> model, const Eigen::Isometry3d& world_T_base, const World& objects,
                   std::vector<std::string> object_names, ArmControllerOptions params, Eigen::VectorXd home,
                   double physics_period_s)
    : model_(std::move(model)),
      world_T_base_(world_T_base),
      kin_(*model_),
      controller_(params),
      arm_(*model_, world_T_base, objects, std::move(object_names), physics_period_s),
      home_(std::move(home)),
      period_ns_(std::llround(physics_period_s * 1e9)) {
  if (home_.size() != kin_.dof()) home_ = 0.5 * (kin_.lower() + kin_.upper());
  reset_joints(home_.cwiseMax(kin_.lower()).cwiseMin(kin_.upper()));
}

Eigen::Isometry3d ArmRobot::reported_world_T_camera() const {
  const Eigen::Isometry3d w_T_c = believed_kin_ ? world_T_base_ * believed_kin_->base_T_camera(q_) : world_T_camera_;
  return camera_T_believed_.matrix().isIdentity(0) ? w_T_c : w_T_c * camera_T_believed_;
}

void ArmRobot::set_belief(const RobotBelief& belief) {
  camera_T_believed_ = belief.camera_T_believed;
  believed_kin_.reset();
  believed_model_.reset();
  if (belief.link_scale.empty() && belief.joint_offset_rad.empty()) return;
  auto m = std::make_shared<RobotModel>(*model_);
  for (std::size_t i = 0; i < m->chain.size(); ++i) {
    ChainSegment& seg = m->chain[i];
    if (i < belief.link_scale.size()) seg.parent_T_origin.translation() *= belief.link_scale[i];
    // a joint whose zero is off: the controller reads q where the joint is at q + offset
    if (i < belief.joint_offset_rad.size() && seg.type == JointType::kRevolute)
      seg.parent_T_origin.rotate(Eigen::AngleAxisd(belief.joint_offset_rad[i], seg.axis));
  }
  believed_model_ = std::move(m);
  believed_kin_ = std::make_unique<ArmKinematics>(*believed_model_);
}

void ArmRobot::sync() {
  q_ = arm_.q();
  qdot_ = arm_.qdot();
  world_T_camera_ = world_T_base_ * kin_.base_T_camera(q_);
}

std::optional<Eigen::VectorXd> ArmRobot::solve(const Eigen::Isometry3d& world_T_camera, const Eigen::VectorXd& seed,
                                               std::string* why) const {
  return kin_.inverse(world_T_base_.inverse() * world_T_camera, seed, why);
}

void ArmRobot::pin(const Eigen::Isometry3d& world_T_camera, const Eigen::VectorXd& q) {
  if (q.size() == kin_.dof()) pinned_.emplace_back(world_T_camera, q);
}

void ArmRobot::reset(const Eigen::Isometry3d& world_T_camera) {
  for (const auto& [pose, q] : pinned_)
    if (pose.matrix() == world_T_camera.matrix()) return reset_joints(q);
  std::string why;
  // from home: the same pose gives the same joints whatever the arm did before
  const auto q = solve(world_T_camera, home_, &why);
  if (!q) throw std::invalid_argument("the arm cannot place the camera there: " + why);
  reset_joints(*q);
}

void ArmRobot::reset_joints(const Eigen::VectorXd& q) {
  if (q.size() != kin_.dof() || !kin_.within_limits(q))
    throw std::invalid_argument("joint angles outside the limits of " + model_->file.filename().string());
  arm_.reset(q);
  q_ref_ = q;
  carry_ns_ = 0;
  fault_.reset();
  sync();
  // Bullet holds the joints as floats: the camera pose is that of the angles it holds
  if (const auto c = arm_.contact()) throw std::invalid_argument("the arm would be in collision there: " + *c);
}

MotionReport ArmRobot::move(const Vector6d& twist_c, double dt_s, const Workspace& workspace) {
  MotionReport r;
  if (!twist_c.allFinite() || !std::isfinite(dt_s) || dt_s < 0)
    throw std::invalid_argument("ArmRobot::move: twist and dt must be finite (dt >= 0)");
  if (fault_) {
    r.limits = kLimitCollision;
    return r;
  }
  carry_ns_ += std::llround(dt_s * 1e9);
  const std::int64_t steps = carry_ns_ / period_ns_;
  carry_ns_ -= steps * period_ns_;
  const double h = static_cast<double>(period_ns_) * 1e-9;
  bool stopped = false;
  // the controller moves the camera it believes in: its twist, in the frame of the model's
  // camera link, is the commanded one carried over the hand-eye error
  const ArmKinematics& ck = believed_kin_ ? *believed_kin_ : kin_;
  const bool exact_hand_eye = camera_T_believed_.matrix().isIdentity(0);
  const Vector6d command = exact_hand_eye ? twist_c : transform_twist(camera_T_believed_, twist_c);
  for (std::int64_t k = 0; k < steps; ++k) {
    ArmCommand cmd = stopped ? ArmCommand{Eigen::VectorXd::Zero(kin_.dof())} : controller_.step(ck, q_, command, h);
    if (!stopped) {
      // the camera stays in the workspace: a step that would leave it is not commanded
      const Eigen::Vector3d next = world_T_camera_ * (cmd.twist.head<3>() * h);
      if (!cmd.qdot.isZero(0) && !workspace.contains(next)) {
        cmd.qdot.setZero();
        cmd.twist.setZero();
        cmd.limits |= kLimitWorkspace;
        stopped = true;
        r.event = "a twist would take the camera out of the workspace: robot stopped";
      }
      r.limits |= cmd.limits;
      r.applied += cmd.twist / static_cast<double>(steps);
    }
    q_ref_ += cmd.qdot * h;
    const Eigen::VectorXd before = q_;
    const auto contact = arm_.step(cmd.qdot, q_ref_);
    sync();
    if (!q_.allFinite() || !qdot_.allFinite()) {
      // a physics blow-up (absurd inertias in a URDF): stop where the arm last was
      arm_.reset(before);
      q_ref_ = before;
      sync();
      fault_ = "the physics diverged (check the URDF's inertias)";
      r.limits |= kLimitCollision;
      r.event = *fault_ + ": robot stopped until RESET";
      break;
    }
    if (contact) {
      fault_ = *contact;
      r.limits |= kLimitCollision;
      r.event = "collision: " + *contact + ": robot stopped until RESET";
      break;
    }
  }
  return r;
}

std::vector<Eigen::Isometry3d> ArmRobot::world_T_links() const {
  std::vector<Eigen::Isometry3d> poses = kin_.link_poses(q_);
  for (auto& p : poses) p = world_T_base_ * p;
  return poses;
}

}  // namespace sim
