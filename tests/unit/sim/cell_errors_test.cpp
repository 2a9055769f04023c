#include "sim/scenario/cell_errors.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "sim/geometry/se3.hpp"
#include "sim/robot/robot.hpp"

namespace sim {
namespace {

TEST(CellErrors, ZeroMagnitudesDrawTheIdentity) {
  const DrawnErrors d = draw_errors({}, 42, 7);
  EXPECT_EQ(d.fx_scale, 1.0);
  EXPECT_EQ(d.fy_scale, 1.0);
  EXPECT_EQ(d.principal_shift_px, Eigen::Vector2d::Zero());
  EXPECT_EQ(d.k1_shift, 0.0);
  EXPECT_TRUE(d.projector_delta.matrix().isIdentity(0));
  EXPECT_TRUE(d.robot.exact());
  EXPECT_FALSE(CalibrationErrors{}.any());
}

TEST(CellErrors, MagnitudesAreExactAndDirectionsFollowTheSeed) {
  CalibrationErrors e;
  e.focal_pct = 2;
  e.principal_point_px = 5;
  e.projector_position_mm = 10;
  e.projector_rotation_deg = 1;
  e.hand_eye_position_mm = 3;
  e.hand_eye_rotation_deg = 0.5;
  e.link_length_pct = 1;
  e.joint_offset_deg = 0.2;
  const DrawnErrors a = draw_errors(e, 1, 6), b = draw_errors(e, 1, 6), c = draw_errors(e, 2, 6);
  EXPECT_NEAR(std::abs(a.fx_scale - 1), 0.02, 1e-15);
  EXPECT_NEAR(std::abs(a.fy_scale - 1), 0.02, 1e-15);
  EXPECT_NEAR(a.principal_shift_px.norm(), 5, 1e-12);
  EXPECT_NEAR(1e3 * a.projector_delta.translation().norm(), 10, 1e-9);
  EXPECT_NEAR(Eigen::AngleAxisd(a.projector_delta.rotation()).angle() * 180 / M_PI, 1, 1e-9);
  EXPECT_NEAR(1e3 * a.robot.camera_T_believed.translation().norm(), 3, 1e-9);
  ASSERT_EQ(a.robot.link_scale.size(), 6u);
  for (double s : a.robot.link_scale) EXPECT_NEAR(std::abs(s - 1), 0.01, 1e-15);
  for (double q : a.robot.joint_offset_rad) EXPECT_NEAR(std::abs(q) * 180 / M_PI, 0.2, 1e-12);
  // the same seed, the same draw; another seed, other directions
  EXPECT_TRUE(a.projector_delta.matrix() == b.projector_delta.matrix());
  EXPECT_FALSE(a.projector_delta.matrix().isApprox(c.projector_delta.matrix(), 1e-6));
  // a seed in the errors fixes the draw whatever the run's seed
  e.seed = 9;
  EXPECT_TRUE(draw_errors(e, 1, 6).projector_delta.matrix() == draw_errors(e, 2, 6).projector_delta.matrix());
}

TEST(CellErrors, SettingsAreCheckedAndNamed) {
  CalibrationErrors e;
  set_error(e, "focal_pct=1.5");
  EXPECT_EQ(e.focal_pct, 1.5);
  set_error(e, "seed=12");
  EXPECT_EQ(e.seed, 12u);
  const auto fails = [&](const std::string& a, const std::string& words) {
    try {
      set_error(e, a);
      ADD_FAILURE() << a << " was accepted";
    } catch (const std::invalid_argument& ex) {
      EXPECT_NE(std::string(ex.what()).find(words), std::string::npos) << ex.what();
    }
  };
  fails("focal_pct=1e300", "outside");
  fails("focal_pct=-1", "outside");
  fails("focal_pct=nan", "not a number");
  fails("focal_pct=1x", "not a number");
  fails("focal", "NAME=VALUE");
  fails("lens_pct=1", "unknown");
  fails("seed=-3", "integer");
  Latency l;
  set_latency(l, "processing_frames=2");
  set_latency(l, "actuation_s=0.01");
  EXPECT_EQ(l.processing_frames, 2);
  EXPECT_TRUE(l.any());
  EXPECT_THROW(set_latency(l, "processing_frames=1.5"), std::invalid_argument);
  EXPECT_THROW(set_latency(l, "processing_frames=51"), std::invalid_argument);  // bounds the twist queue
  EXPECT_THROW(set_latency(l, "actuation_s=2"), std::invalid_argument);
  EXPECT_THROW(set_latency(l, "jitter_s=0.1"), std::invalid_argument);
}

// A hand-eye error: the robot reports the camera it believes in and moves that one as told;
// the true camera, rigidly attached, follows.
TEST(CellErrors, HandEyeErrorMovesTheBelievedCameraAsCommanded) {
  const Eigen::Isometry3d start = pose_from_xyz_rxyz(0.1, 0.2, 0.5, 0.1, -0.2, 0.3);
  FreeFlyingCamera cam(start, 10, 10);
  RobotBelief belief;
  belief.camera_T_believed = pose_from_xyz_rxyz(0.01, -0.02, 0.005, 0.02, 0.01, -0.03);
  cam.set_belief(belief);
  EXPECT_TRUE(cam.reported_world_T_camera().isApprox(start * belief.camera_T_believed, 1e-12));
  Vector6d v;
  v << 0.05, -0.02, 0.03, 0.1, -0.2, 0.05;
  Workspace everywhere;
  everywhere.min_m = Eigen::Vector3d::Constant(-10);
  everywhere.max_m = Eigen::Vector3d::Constant(10);
  const Eigen::Isometry3d believed_before = cam.reported_world_T_camera();
  cam.move(v, 0.1, everywhere);
  EXPECT_TRUE(cam.reported_world_T_camera().isApprox(believed_before * se3_exp(v * 0.1), 1e-9));
  // and the true camera did not move by v itself
  EXPECT_FALSE(cam.world_T_camera().isApprox(start * se3_exp(v * 0.1), 1e-6));
}

}  // namespace
}  // namespace sim
