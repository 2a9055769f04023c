#include "sim/geometry/se3.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "sim/robot/robot.hpp"

namespace sim {
namespace {

// A screw motion written from its geometry, not from the exponential formula: rotation by
// angle th about a unit axis through point q, plus translation d along the axis.
Eigen::Isometry3d screw(const Eigen::Vector3d& axis, const Eigen::Vector3d& q, double th, double d) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(th, axis).toRotationMatrix();
  T.translation() = q - T.linear() * q + d * axis;
  return T;
}

TEST(Se3Exp, MatchesAClosedFormScrewMotion) {
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, -0.5).normalized();
  const Eigen::Vector3d q(0.3, -0.2, 0.9);  // a point on the screw axis
  const double omega = 0.7, pitch = 0.05;   // rad/s, m/rad
  // twist of that screw: w = omega axis, v = -w x q + pitch * w
  Vector6d twist;
  twist.tail<3>() = omega * axis;
  twist.head<3>() = -(omega * axis).cross(q) + pitch * omega * axis;
  for (double t : {0.01, 0.04, 1.0, 5.0}) {
    const Eigen::Isometry3d expected = screw(axis, q, omega * t, pitch * omega * t);
    const Eigen::Isometry3d got = se3_exp(twist * t);
    EXPECT_LT((got.matrix() - expected.matrix()).cwiseAbs().maxCoeff(), 1e-12) << "t = " << t;
  }
}

TEST(Se3Exp, PureTranslationAndTinyRotation) {
  Vector6d v;
  v << 0.1, -0.2, 0.3, 0, 0, 0;
  EXPECT_TRUE(se3_exp(v).translation().isApprox(Eigen::Vector3d(0.1, -0.2, 0.3)));
  v << 0.1, 0, 0, 1e-9, 0, 0;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(1e-9, Eigen::Vector3d::UnitX()).toRotationMatrix();
  EXPECT_LT((se3_exp(v).linear() - R).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_TRUE(se3_exp(v).translation().isApprox(Eigen::Vector3d(0.1, 0, 0), 1e-12));
}

TEST(Se3Log, InvertsExp) {
  Vector6d v;
  v << 0.2, -0.1, 0.05, 0.3, -0.6, 0.2;
  EXPECT_TRUE(se3_log(se3_exp(v)).isApprox(v, 1e-10));
}

// the pose part of the way along a screw motion is the screw's pose at that share of its angle
// and its advance, measured from either end's frame
TEST(Se3Interpolate, FollowsTheScrewBetweenTwoPoses) {
  const Eigen::Vector3d axis = Eigen::Vector3d(-0.4, 1, 0.3).normalized();
  const Eigen::Vector3d q(0.1, 0.5, -0.2);
  const Eigen::Isometry3d a = pose_from_xyz_rxyz(0.6, -0.1, 0.4, 0.2, -0.3, 1.1);
  const Eigen::Isometry3d b = a * screw(axis, q, 0.5, 0.02);
  EXPECT_LT((interpolate(a, b, 0).matrix() - a.matrix()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((interpolate(a, b, 1).matrix() - b.matrix()).cwiseAbs().maxCoeff(), 1e-12);
  for (double t : {0.25, 0.5, 0.9}) {
    const Eigen::Isometry3d expected = a * screw(axis, q, 0.5 * t, 0.02 * t);
    EXPECT_LT((interpolate(a, b, t).matrix() - expected.matrix()).cwiseAbs().maxCoeff(), 1e-12) << "t = " << t;
    EXPECT_LT((interpolate(b, a, 1 - t).matrix() - expected.matrix()).cwiseAbs().maxCoeff(), 1e-12) << "t = " << t;
  }
}

TEST(FreeFlyingCamera, IntegratesOverManyStepsExactly) {
  FreeFlyingCamera cam(Eigen::Isometry3d::Identity(), 10, 10);
  Vector6d v;
  v << 0.1, 0.0, -0.05, 0.0, 0.2, 0.1;
  for (int k = 0; k < 100; ++k) cam.apply_twist(v, 0.04);
  // constant body twist: 100 steps of exp(0.04 v) = exp(4 v)
  EXPECT_LT((cam.world_T_camera().matrix() - se3_exp(4.0 * v).matrix()).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(FreeFlyingCamera, ClampsEachAxisToItsLimit) {
  FreeFlyingCamera cam(Eigen::Isometry3d::Identity(), 0.5, 1.0);
  Vector6d v;
  v << 2.0, -0.1, -3.0, 0.0, 5.0, -0.5;
  const Vector6d applied = cam.apply_twist(v, 0.04);
  Vector6d expected;
  expected << 0.5, -0.1, -0.5, 0.0, 1.0, -0.5;
  EXPECT_TRUE(applied.isApprox(expected));
}

TEST(FreeFlyingCamera, RejectsNonFiniteTwistWithoutMoving) {
  FreeFlyingCamera cam(Eigen::Isometry3d::Identity(), 0.5, 1.0);
  Vector6d v = Vector6d::Zero();
  v[2] = std::nan("");
  EXPECT_THROW(cam.apply_twist(v, 0.04), std::invalid_argument);
  EXPECT_TRUE(cam.world_T_camera().isApprox(Eigen::Isometry3d::Identity()));
}

}  // namespace
}  // namespace sim
