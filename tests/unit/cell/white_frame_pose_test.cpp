// Where each frame's white reference frame is taken (sim::WhiteFramePose): on the way the
// camera came from the frame before, the lead's share of a frame period back; at the frame's
// own pose when it did not come by a twist; a repeated frame as first sent.
#include "sim/session/white_frame_pose.hpp"

#include <gtest/gtest.h>

#include "sim/geometry/se3.hpp"

namespace sim {
namespace {

FrameOrder frame(std::uint64_t k, const Eigen::Isometry3d& pose, bool applies, bool repeat = false) {
  FrameOrder f;
  f.index = k;
  f.scene_world_T_camera = pose;
  f.applies_twist = applies;
  f.repeat = repeat;
  return f;
}

bool same(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.matrix() - b.matrix()).cwiseAbs().maxCoeff() < 1e-12;
}

TEST(WhiteFramePose, TakenOnTheWayTheCameraCame) {
  const Eigen::Isometry3d p0 = pose_from_xyz_rxyz(0.6, 0, 0.4, 0.1, 0.2, 0.3);
  const Eigen::Isometry3d p1 = pose_from_xyz_rxyz(0.61, 0.005, 0.39, 0.11, 0.19, 0.31);
  const Eigen::Isometry3d p2 = pose_from_xyz_rxyz(0.62, 0.01, 0.38, 0.12, 0.18, 0.32);
  WhiteFramePose w(0.25);
  EXPECT_TRUE(same(w.at(frame(0, p0, false)), p0));  // not moving: where the frame is
  EXPECT_TRUE(same(w.at(frame(1, p0, true)), p0));   // START: the camera was still before it
  const Eigen::Isometry3d at2 = w.at(frame(2, p1, true));
  EXPECT_TRUE(same(at2, interpolate(p1, p0, 0.25)));
  EXPECT_GT(translation_error(at2, p1), 1e-3);
  // lockstep sends frame 2 again: its white frame as first sent, not from frame 2 to itself
  EXPECT_TRUE(same(w.at(frame(2, p1, true, true)), at2));
  EXPECT_TRUE(same(w.at(frame(3, p2, true)), interpolate(p2, p1, 0.25)));
  // a RESET moved the camera: the frame after it is not reached from the one before
  w.forget();
  EXPECT_TRUE(same(w.at(frame(4, p0, true)), p0));
  // a pause: the frame applies no twist, and the next one starts from still
  EXPECT_TRUE(same(w.at(frame(5, p1, false)), p1));
  EXPECT_TRUE(same(w.at(frame(6, p1, true)), p1));
  WhiteFramePose at_once(0);
  at_once.at(frame(0, p0, true));
  EXPECT_TRUE(same(at_once.at(frame(1, p1, true)), p1));
}

}  // namespace
}  // namespace sim
