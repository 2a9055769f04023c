#include "sim/arm/arm_controller.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

namespace sim {

namespace {
double condition_of(const Eigen::JacobiSVD<Matrix6Xd>& svd) {
  const auto& s = svd.singularValues();
  const double lo = s[s.size() - 1];
  return lo > 1e-12 ? s[0] / lo : std::numeric_limits<double>::infinity();
}

// the share of the step q + qdot dt that keeps every joint inside its limits less the margin
double joint_room(const ArmKinematics& kin, const Eigen::VectorXd& q, const Eigen::VectorXd& qdot, double dt,
                  double margin) {
  double fit = 1;
  for (int i = 0; i < kin.dof(); ++i) {
    const double step = qdot[i] * dt;
    if (step > 0) {
      const double room = kin.upper()[i] - margin - q[i];
      if (step > room) fit = std::min(fit, std::max(0.0, room) / step);
    } else if (step < 0) {
      const double room = q[i] - (kin.lower()[i] + margin);
      if (-step > room) fit = std::min(fit, std::max(0.0, room) / -step);
    }
  }
  return fit;
}
}  // namespace

ArmCommand ArmController::step(const ArmKinematics& kin, const Eigen::VectorXd& q, const Vector6d& twist_c,
                               double dt) const {
  ArmCommand out;
  const int n = kin.dof();
  out.qdot = Eigen::VectorXd::Zero(n);
  if (!twist_c.allFinite() || q.size() != n || !q.allFinite() || !(dt > 0)) return out;

  // 1. Cartesian speed, direction kept
  Vector6d v = twist_c;
  double cart = 1;
  const double lin = v.head<3>().norm(), ang = v.tail<3>().norm();
  if (lin > p_.max_linear_mps) cart = std::min(cart, p_.max_linear_mps / lin);
  if (ang > p_.max_angular_radps) cart = std::min(cart, p_.max_angular_radps / ang);
  if (cart < 1) {
    v *= cart;
    out.limits |= kLimitCartesianSpeed;
  }
  if (v.isZero(0)) return out;

  // 2. damped least squares
  const Matrix6Xd J = kin.jacobian_camera(q);
  const Eigen::JacobiSVD<Matrix6Xd> svd(J, Eigen::ComputeFullU);
  const auto& sv = svd.singularValues();
  const double sigma_min = sv.size() >= 6 ? sv[5] : 0.0;  // fewer than 6 joints: always singular in some direction
  out.condition = sv.size() >= 6 ? condition_of(svd) : std::numeric_limits<double>::infinity();
  double lambda2 = 0;
  if (sigma_min < p_.damping_threshold) {
    const double r = sigma_min / p_.damping_threshold;
    lambda2 = (1 - r * r) * p_.damping * p_.damping;
  }
  const Eigen::Matrix<double, 6, 6> A = J * J.transpose() + lambda2 * Eigen::Matrix<double, 6, 6>::Identity();
  Eigen::VectorXd qdot = J.transpose() * A.ldlt().solve(v);
  double scale = 1;

  // 3. singularity, as MoveIt Servo: which way along the least singular direction makes the
  //    condition number grow, and does the command go that way?
  if (out.condition > p_.slowdown_condition) {
    Vector6d towards = svd.matrixU().col(5);
    const Eigen::VectorXd dq = J.transpose() * A.ldlt().solve(towards) * 1e-3;
    const Eigen::JacobiSVD<Matrix6Xd> ahead(kin.jacobian_camera(q + dq));
    if (condition_of(ahead) < out.condition) towards = -towards;
    if (towards.dot(v) > 0) {
      if (out.condition >= p_.stop_condition) {
        scale = 0;
        out.limits |= kLimitSingularityStop;
      } else {
        scale = 1 - (out.condition - p_.slowdown_condition) / (p_.stop_condition - p_.slowdown_condition);
        out.limits |= kLimitSingularitySlowdown;
      }
    }
  }
  qdot *= scale;

  // 4. joint position limits with a margin: the step stops short of the margin
  const double fit = joint_room(kin, q, qdot, dt, p_.joint_margin_rad);
  if (fit < 1) {
    qdot *= fit;
    scale *= fit;
    out.limits |= kLimitJointPosition;
  }

  // 5. joint velocity limits, all joints together
  const Eigen::VectorXd vmax = kin.max_velocity();
  double vel = 1;
  for (int i = 0; i < n; ++i)
    if (std::abs(qdot[i]) > vmax[i]) vel = std::min(vel, vmax[i] / std::abs(qdot[i]));
  if (vel < 1) {
    qdot *= vel;
    scale *= vel;
    out.limits |= kLimitJointVelocity;
  }
  out.qdot = qdot;
  out.scale = scale * cart;
  out.twist = J * qdot;
  return out;
}

}  // namespace sim
