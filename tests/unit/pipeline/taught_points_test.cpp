// The taught points (servo/pipeline/taught_points.hpp) on hand-made features: a spot away from
// the point its id lit at teaching is held out, an error that moves every spot alike is not,
// and an id that was not taught is not checked.
#include "servo/pipeline/taught_points.hpp"

#include <gtest/gtest.h>

namespace servo {
namespace {

constexpr double kF = 800;  // focal length (px)

// a 6 x 6 grid of features on a plane 0.8 m ahead of the camera, with their depths
std::vector<control::Feature> grid() {
  std::vector<control::Feature> f;
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) f.push_back({r, c, -0.15 + 0.06 * c, -0.15 + 0.06 * r, 0.8, std::nullopt});
  return f;
}

// the features of a camera at `wTc` looking at the taught points
std::vector<control::Feature> seen_from(const std::vector<TaughtPoint>& taught, const Eigen::Isometry3d& wTc) {
  std::vector<control::Feature> f;
  for (const TaughtPoint& t : taught) {
    const Eigen::Vector3d p = wTc.inverse() * t.world;
    f.push_back({t.row, t.col, p.x() / p.z(), p.y() / p.z(), p.z(), std::nullopt});
  }
  return f;
}

Eigen::Isometry3d moved() {
  Eigen::Isometry3d wTc = Eigen::Isometry3d::Identity();
  wTc.translate(Eigen::Vector3d(0.03, -0.02, 0.05));
  wTc.rotate(Eigen::AngleAxisd(0.1, Eigen::Vector3d(0.3, 1, 0.2).normalized()));
  return wTc;
}

TEST(TaughtPoints, AreTheLitPointsInTheWorldSortedById) {
  std::vector<control::Feature> f = grid();
  f[7].z.reset();  // no depth: nothing to hold it to
  std::swap(f[0], f[20]);
  Eigen::Isometry3d wTc = Eigen::Isometry3d::Identity();
  wTc.translation() = Eigen::Vector3d(1, 2, 3);
  const std::vector<TaughtPoint> t = taught_points(f, wTc);
  ASSERT_EQ(t.size(), 35U);
  for (std::size_t i = 1; i < t.size(); ++i)
    EXPECT_LT(std::pair(t[i - 1].row, t[i - 1].col), std::pair(t[i].row, t[i].col));
  EXPECT_TRUE(t[0].world.isApprox(Eigen::Vector3d(1 - 0.15 * 0.8, 2 - 0.15 * 0.8, 3 + 0.8)));
}

TEST(TaughtPoints, ASpotAwayFromItsTaughtPointIsHeldOut) {
  const std::vector<TaughtPoint> taught = taught_points(grid(), Eigen::Isometry3d::Identity());
  const Eigen::Isometry3d wTc = moved();
  std::vector<control::Feature> f = seen_from(taught, wTc);
  for (std::size_t i = 0; i < f.size(); ++i) f[i].x += (i % 5) * 0.05 / kF;  // centroid noise, 0-0.2 px
  f[10].y += 2.5 / kF;  // a spill along its line: 2.5 px off where its spot lies
  f.push_back({9, 9, 0.0, 0.0, 0.8, std::nullopt});  // an id never taught: not checked
  const TaughtCheck c = check_taught(f, taught, wTc, kF, kF, vision::GrownLimit{});
  EXPECT_EQ(c.checked, 36);
  EXPECT_EQ(c.kept_out, 1);
  EXPECT_TRUE(c.off[10]);
  EXPECT_FALSE(c.off[36]);
  EXPECT_DOUBLE_EQ(c.limit_px, 1.0) << "residuals of a tenth of a pixel: the floor";
}

// A pose that lags its frame, or a calibration error, moves every spot alike: the limit follows
// the frame's median, and the law keeps its features.
TEST(TaughtPoints, AnErrorThatMovesEverySpotAlikeLoosensTheLimit) {
  const std::vector<TaughtPoint> taught = taught_points(grid(), Eigen::Isometry3d::Identity());
  const Eigen::Isometry3d wTc = moved();
  std::vector<control::Feature> f = seen_from(taught, wTc);
  for (control::Feature& x : f) x.x += 4.0 / kF;
  const TaughtCheck c = check_taught(f, taught, wTc, kF, kF, vision::GrownLimit{});
  EXPECT_EQ(c.kept_out, 0);
  EXPECT_NEAR(c.limit_px, 16.0, 1e-6);
}

TEST(TaughtPoints, TooFewToTellAFrameChecksNothingAndAPointBehindTheCameraIsOff) {
  std::vector<TaughtPoint> taught = taught_points(grid(), Eigen::Isometry3d::Identity());
  std::vector<control::Feature> f = seen_from(taught, Eigen::Isometry3d::Identity());
  f.resize(8);
  f[2].x += 10 / kF;
  TaughtCheck c = check_taught(f, taught, Eigen::Isometry3d::Identity(), kF, kF, vision::GrownLimit{});
  EXPECT_EQ(c.kept_out, 0) << "under a window's 9 spots the frame's residuals say nothing";
  f = seen_from(taught, Eigen::Isometry3d::Identity());
  taught[5].world.z() = -0.5;
  c = check_taught(f, taught, Eigen::Isometry3d::Identity(), kF, kF, vision::GrownLimit{});
  EXPECT_EQ(c.kept_out, 1);
  EXPECT_TRUE(c.off[5]);
}

}  // namespace
}  // namespace servo
