#include "sim/geometry/se3.hpp"

#include <cmath>

namespace sim {
namespace {

Eigen::Matrix3d skew(const Eigen::Vector3d& w) {
  Eigen::Matrix3d S;
  S << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  return S;
}

}  // namespace

Eigen::Isometry3d se3_exp(const Vector6d& twist) {
  const Eigen::Vector3d v = twist.head<3>();
  const Eigen::Vector3d w = twist.tail<3>();
  const double th = w.norm();
  const Eigen::Matrix3d W = skew(w);
  const Eigen::Matrix3d W2 = W * W;
  double a, b, c;  // R = I + a W + b W^2, V = I + b W + c W^2
  if (th < 1e-6) {
    const double th2 = th * th;
    a = 1.0 - th2 / 6.0;
    b = 0.5 - th2 / 24.0;
    c = 1.0 / 6.0 - th2 / 120.0;
  } else {
    a = std::sin(th) / th;
    b = (1.0 - std::cos(th)) / (th * th);
    c = (th - std::sin(th)) / (th * th * th);
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Matrix3d::Identity() + a * W + b * W2;
  T.translation() = (Eigen::Matrix3d::Identity() + b * W + c * W2) * v;
  return T;
}

Vector6d se3_log(const Eigen::Isometry3d& T) {
  const Eigen::AngleAxisd aa(T.rotation());
  const double th = aa.angle();
  const Eigen::Vector3d w = aa.axis() * th;
  const Eigen::Matrix3d W = skew(w);
  Eigen::Matrix3d Vinv = Eigen::Matrix3d::Identity() - 0.5 * W;
  if (th > 1e-6) {
    const double k = (1.0 - th * std::sin(th) / (2.0 * (1.0 - std::cos(th)))) / (th * th);
    Vinv += k * W * W;
  } else {
    Vinv += W * W / 12.0;
  }
  Vector6d out;
  out.head<3>() = Vinv * T.translation();
  out.tail<3>() = w;
  return out;
}

Eigen::Isometry3d interpolate(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double t) {
  return a * se3_exp(t * se3_log(a.inverse() * b));
}

Eigen::Isometry3d pose_from_xyz_rxyz(double x, double y, double z, double rx, double ry, double rz) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  T.linear() = (Eigen::AngleAxisd(rx, Eigen::Vector3d::UnitX()) * Eigen::AngleAxisd(ry, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(rz, Eigen::Vector3d::UnitZ()))
                   .toRotationMatrix();
  return T;
}

Eigen::Isometry3d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, const Eigen::Vector3d& up) {
  const Eigen::Vector3d z = (target - eye).normalized();
  Eigen::Vector3d x = z.cross(up);
  if (x.norm() < 1e-9) x = z.unitOrthogonal();
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = x;
  T.linear().col(1) = y;
  T.linear().col(2) = z;
  T.translation() = eye;
  return T;
}

double translation_error(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.translation() - b.translation()).norm();
}

double rotation_error(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.rotation().transpose() * b.rotation()).angle();
}

GoalError goal_error(const Eigen::Isometry3d& wTc, const Eigen::Isometry3d& wTd, const std::optional<GoalPlane>& plane) {
  if (!plane) return {translation_error(wTc, wTd), rotation_error(wTc, wTd)};
  const Eigen::Vector3d& n = plane->n_w;
  const double distance_c = plane->d - n.dot(wTc.translation()), distance_d = plane->d - n.dot(wTd.translation());
  const Eigen::Vector3d seen_c = wTc.rotation().transpose() * n, seen_d = wTd.rotation().transpose() * n;
  return {std::abs(distance_c - distance_d), std::atan2(seen_c.cross(seen_d).norm(), seen_c.dot(seen_d))};
}

Vector6d transform_twist(const Eigen::Isometry3d& a_T_b, const Vector6d& twist_b) {
  const Eigen::Matrix3d R = a_T_b.rotation();
  Vector6d out;
  out.tail<3>() = R * twist_b.tail<3>();
  out.head<3>() = R * twist_b.head<3>() + a_T_b.translation().cross(out.tail<3>());
  return out;
}

}  // namespace sim
