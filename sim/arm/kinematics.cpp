#include "sim/arm/kinematics.hpp"

#include <kdl/chain.hpp>
#include <kdl/chainiksolverpos_lma.hpp>
#include <kdl/chainjnttojacsolver.hpp>

#include <cmath>
#include <random>

#include "sim/geometry/se3.hpp"

namespace sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

KDL::Frame to_kdl(const Eigen::Isometry3d& t) {
  const Eigen::Matrix3d R = t.rotation();
  return KDL::Frame(KDL::Rotation(R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2)),
                    KDL::Vector(t.translation().x(), t.translation().y(), t.translation().z()));
}

Eigen::Isometry3d from_kdl(const KDL::Frame& f) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) t.linear()(r, c) = f.M(r, c);
  t.translation() = Eigen::Vector3d(f.p.x(), f.p.y(), f.p.z());
  return t;
}

KDL::JntArray to_jnt(const Eigen::VectorXd& q) {
  KDL::JntArray a(static_cast<unsigned>(q.size()));
  a.data = q;
  return a;
}

}  // namespace

struct ArmKinematics::Kdl {
  KDL::Chain chain;
  std::unique_ptr<KDL::ChainJntToJacSolver> jac;
  std::unique_ptr<KDL::ChainIkSolverPos_LMA> ik;
};

ArmKinematics::ArmKinematics(const RobotModel& model) : kdl_(std::make_unique<Kdl>()) {
  for (const ChainSegment& s : model.chain) {
    const KDL::Frame origin = to_kdl(s.parent_T_origin);
    const KDL::Vector axis = origin.M * KDL::Vector(s.axis.x(), s.axis.y(), s.axis.z());
    // the joint's axis and origin in the parent frame, then the origin as the segment's
    // tip: pose(q) = Rot(axis, q) about the origin * origin = origin * Rot(local axis, q)
    KDL::Joint joint = s.type == JointType::kRevolute    ? KDL::Joint(s.joint, origin.p, axis, KDL::Joint::RotAxis)
                       : s.type == JointType::kPrismatic ? KDL::Joint(s.joint, origin.p, axis, KDL::Joint::TransAxis)
                                                         : KDL::Joint(s.joint, KDL::Joint::None);
    kdl_->chain.addSegment(KDL::Segment(s.link, joint, origin));
  }
  dof_ = static_cast<int>(kdl_->chain.getNrOfJoints());
  lower_ = model.lower_limits();
  upper_ = model.upper_limits();
  velocity_ = model.velocity_limits();
  kdl_->jac = std::make_unique<KDL::ChainJntToJacSolver>(kdl_->chain);
  Eigen::Matrix<double, 6, 1> weights = Eigen::Matrix<double, 6, 1>::Ones();
  kdl_->ik = std::make_unique<KDL::ChainIkSolverPos_LMA>(kdl_->chain, weights, 1e-13, 300, 1e-15);
}

ArmKinematics::~ArmKinematics() = default;

std::vector<Eigen::Isometry3d> ArmKinematics::link_poses(const Eigen::VectorXd& q) const {
  std::vector<Eigen::Isometry3d> poses{Eigen::Isometry3d::Identity()};
  KDL::Frame t = KDL::Frame::Identity();
  unsigned j = 0;
  for (const KDL::Segment& seg : kdl_->chain.segments) {
    const bool moves = seg.getJoint().getType() != KDL::Joint::None;
    t = t * seg.pose(moves ? q[j] : 0.0);
    j += moves;
    poses.push_back(from_kdl(t));
  }
  return poses;
}

Eigen::Isometry3d ArmKinematics::base_T_camera(const Eigen::VectorXd& q) const { return link_poses(q).back(); }

Matrix6Xd ArmKinematics::jacobian_base(const Eigen::VectorXd& q) const {
  KDL::Jacobian jac(static_cast<unsigned>(dof_));
  kdl_->jac->JntToJac(to_jnt(q), jac);
  return jac.data;
}

Matrix6Xd ArmKinematics::jacobian_camera(const Eigen::VectorXd& q) const {
  const Eigen::Matrix3d Rt = base_T_camera(q).rotation().transpose();
  Matrix6Xd J = jacobian_base(q);
  J.topRows<3>() = Rt * J.topRows<3>();
  J.bottomRows<3>() = Rt * J.bottomRows<3>();
  return J;
}

bool ArmKinematics::within_limits(const Eigen::VectorXd& q, double margin) const {
  return q.size() == dof_ && q.allFinite() && (q.array() >= lower_.array() + margin).all() &&
         (q.array() <= upper_.array() - margin).all();
}

std::optional<Eigen::VectorXd> ArmKinematics::inverse(const Eigen::Isometry3d& goal, const Eigen::VectorXd& seed,
                                                      std::string* why) const {
  const KDL::Frame target = to_kdl(goal);
  std::mt19937_64 rng(0x5EED);  // restarts are the same every call: IK is deterministic
  std::optional<Eigen::VectorXd> best;
  double best_distance = 0;
  int found = 0;
  double nearest_miss = std::numeric_limits<double>::infinity();
  for (int attempt = 0; attempt < 64 && found < 4; ++attempt) {
    Eigen::VectorXd start(dof_);
    if (attempt == 0) {
      start = seed.size() == dof_ ? seed : 0.5 * (lower_ + upper_);
    } else {
      for (int i = 0; i < dof_; ++i) start[i] = std::uniform_real_distribution<double>(lower_[i], upper_[i])(rng);
    }
    KDL::JntArray out(static_cast<unsigned>(dof_));
    kdl_->ik->CartToJnt(to_jnt(start), target, out);
    Eigen::VectorXd q = out.data;
    if (!q.allFinite()) continue;
    // revolute joints: the equivalent angle (2 pi apart) within the limits, nearest the seed
    for (int i = 0; i < dof_; ++i) {
      const double ref = seed.size() == dof_ ? seed[i] : 0.0;
      double best_a = q[i];
      bool ok = false;
      for (int k = -2; k <= 2; ++k) {
        const double a = q[i] + 2 * kPi * k;
        if (a < lower_[i] || a > upper_[i]) continue;
        if (!ok || std::abs(a - ref) < std::abs(best_a - ref)) best_a = a;
        ok = true;
      }
      q[i] = best_a;
    }
    const Eigen::Isometry3d reached = base_T_camera(q);
    const double err = translation_error(reached, goal) + rotation_error(reached, goal);
    nearest_miss = std::min(nearest_miss, err);
    if (err > 1e-7 || !within_limits(q)) continue;
    const double d = seed.size() == dof_ ? (q - seed).norm() : q.norm();
    if (!best || d < best_distance) {
      best = q;
      best_distance = d;
    }
    ++found;
    if (attempt == 0) break;  // from the seed itself: the continuous choice
  }
  if (!best && why) {
    char line[160];
    std::snprintf(line, sizeof line, "no joint configuration within the limits reaches it (closest miss %.3g, m + rad)",
                  nearest_miss);
    *why = line;
  }
  return best;
}

}  // namespace sim
