#include "servo/control/control_law.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <cmath>
#include <random>

#include "servo/calibration/camera_intrinsics.hpp"
#include "servo/control/interaction_matrix.hpp"
#include "servo/control/triangulation.hpp"

namespace control {
namespace {

// 3-D points in front of the camera, spread like a pattern on a tilted surface.
std::vector<Eigen::Vector3d> scene_points(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> xy(-0.25, 0.25), dz(-0.1, 0.1);
  std::vector<Eigen::Vector3d> p;
  for (int i = 0; i < n; ++i) {
    const double x = xy(rng), y = xy(rng);
    p.emplace_back(x, y, 0.8 + 0.3 * x + dz(rng));
  }
  return p;
}

// The camera moved by the body twist v for time dt (first-order exact for the linear part,
// exact rotation), and the point re-expressed in the moved camera's frame.
Eigen::Vector3d after_motion(const Eigen::Vector3d& X, const Vector6d& v, double dt) {
  const Eigen::Vector3d w = v.tail<3>();
  const Eigen::Matrix3d R = w.norm() > 0 ? Eigen::AngleAxisd(w.norm() * dt, w.normalized()).toRotationMatrix()
                                         : Eigen::Matrix3d::Identity();
  const Eigen::Vector3d t = v.head<3>() * dt;
  return R.transpose() * (X - t);
}

// the scene points seen from the camera after the motion `offset` (one second of it)
std::vector<Eigen::Vector3d> after_offset(const std::vector<Eigen::Vector3d>& goal, const Vector6d& offset) {
  std::vector<Eigen::Vector3d> now;
  for (const auto& X : goal) now.push_back(after_motion(X, offset, 1.0));
  return now;
}

TEST(InteractionMatrix, MatchesFiniteDifferencesOfTheProjection) {
  const auto pts = scene_points(30, 1);
  Vector6d v;
  v << 0.05, -0.03, 0.08, 0.2, -0.1, 0.3;
  const double dt = 1e-6;
  Eigen::VectorXd xy(2 * pts.size()), Z(pts.size()), numeric(2 * pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    xy[2 * i] = pts[i].x() / pts[i].z();
    xy[2 * i + 1] = pts[i].y() / pts[i].z();
    Z[i] = pts[i].z();
    const Eigen::Vector3d moved = after_motion(pts[i], v, dt);
    numeric[2 * i] = (moved.x() / moved.z() - xy[2 * i]) / dt;
    numeric[2 * i + 1] = (moved.y() / moved.z() - xy[2 * i + 1]) / dt;
  }
  const Eigen::VectorXd analytic = stacked_interaction_matrix(xy, Z) * v;
  EXPECT_LT((analytic - numeric).cwiseAbs().maxCoeff(), 1e-5);
}

std::vector<MatchedPoint> matched(const std::vector<Eigen::Vector3d>& now, const std::vector<Eigen::Vector3d>& goal) {
  std::vector<MatchedPoint> m;
  for (std::size_t i = 0; i < now.size(); ++i)
    m.push_back({0, static_cast<int>(i), now[i].x() / now[i].z(), now[i].y() / now[i].z(), goal[i].x() / goal[i].z(),
                 goal[i].y() / goal[i].z(), now[i].z(), goal[i].z()});
  return m;
}

TEST(ControlLaw, ZeroTwistAtTheGoal) {
  const auto pts = scene_points(50, 2);
  for (auto model : {InteractionModel::kDesiredConstantDepth, InteractionModel::kDesired, InteractionModel::kCurrent,
                     InteractionModel::kMean}) {
    ControlLawOptions p;
    p.model = model;
    const ControlOutput out = compute_control(matched(pts, pts), p);
    EXPECT_EQ(out.status, ControlStatus::kConverged) << to_string(model);
    EXPECT_EQ(out.twist.norm(), 0.0);
    EXPECT_EQ(out.error_norm, 0.0);
  }
}

// With L(s, Z) and exact depths, s - s* decays as exp(-lambda t) in the continuous limit.
TEST(ControlLaw, ExactCurrentModelDecaysExponentiallyAtRateLambda) {
  const auto goal = scene_points(40, 3);
  Vector6d offset;
  offset << 0.01, -0.008, 0.015, 0.01, -0.012, 0.008;  // a small displacement
  std::vector<Eigen::Vector3d> now = after_offset(goal, offset);
  ControlLawOptions p;
  p.model = InteractionModel::kCurrent;
  p.gain = {0.7, 0.7, 0};
  p.max_linear_mps = p.max_angular_radps = 10;
  const auto feature_error = [&](const std::vector<Eigen::Vector3d>& pts) {
    double e = 0;
    for (const auto& m : matched(pts, goal)) e += std::pow(m.x - m.x_star, 2) + std::pow(m.y - m.y_star, 2);
    return std::sqrt(e);
  };
  const double e0 = feature_error(now);
  const double dt = 1e-3;
  const int steps = 1000;  // one second
  for (int k = 0; k < steps; ++k) {
    const ControlOutput out = compute_control(matched(now, goal), p);
    for (auto& X : now) X = after_motion(X, out.twist, dt);
  }
  const double expected = e0 * std::exp(-0.7 * steps * dt);
  EXPECT_NEAR(feature_error(now) / expected, 1.0, 0.02);
}

// Issue 44: the law on image moments brings the camera back from a displacement of the
// paper's size (a few cm, a few degrees) with each model, to the same pose the points give:
// the six moments of a rigid point set fix the pose. Robust weights are per point: refused.
TEST(ControlLaw, TheMomentsAndTheSurfaceBringTheCameraBackWithEveryModel) {
  const auto goal = scene_points(60, 5);
  Vector6d offset;
  offset << 0.04, -0.03, 0.05, 0.06, -0.05, 0.2;
  for (auto model : {InteractionModel::kDesiredConstantDepth, InteractionModel::kDesired, InteractionModel::kCurrent,
                     InteractionModel::kMean})
   for (auto features : {VisualFeatures::kMoments, VisualFeatures::kSurface}) {
    std::vector<Eigen::Vector3d> now = after_offset(goal, offset);
    ControlLawOptions p;
    p.model = model;
    p.z_hat_m = 0.8;
    p.features = features;
    ControlOutput out;
    int k = 0;
    for (; k < 3000 && out.status != ControlStatus::kConverged; ++k) {
      out = compute_control(matched(now, goal), p);
      ASSERT_NE(out.status, ControlStatus::kTooFewPoints) << out.reason;
      for (auto& X : now) X = after_motion(X, out.twist, 0.04);
    }
    // the pose error: every point back where it was, to a fraction of a millimetre
    double worst = 0;
    for (std::size_t i = 0; i < goal.size(); ++i) worst = std::max(worst, (now[i] - goal[i]).norm());
    EXPECT_EQ(out.status, ControlStatus::kConverged) << to_string(features) << ", " << to_string(model) << " after " << k << " iterations";
    EXPECT_LT(worst, 2e-3) << to_string(features) << ", " << to_string(model) << ": a point " << worst * 1e3 << " mm from its place";
  }
  // points on a line give no plane, points on one spot no moments: a safe stop, never a throw
  std::vector<Eigen::Vector3d> line;
  for (int i = 0; i < 8; ++i) line.emplace_back(0.01 * i, 0.02 * i, 0.8 + 0.01 * i);
  for (auto features : {VisualFeatures::kMoments, VisualFeatures::kSurface}) {
    ControlLawOptions p;
    p.model = InteractionModel::kCurrent;
    p.features = features;
    const auto same = std::vector<Eigen::Vector3d>(8, Eigen::Vector3d(0.1, 0.1, 0.8));
    const ControlOutput a = compute_control(matched(line, line), p), b = compute_control(matched(same, same), p);
    EXPECT_EQ(features == VisualFeatures::kSurface ? a.status : b.status, ControlStatus::kTooFewPoints) << a.reason << b.reason;
    EXPECT_TRUE(a.twist.isZero() && b.twist.isZero());
  }
  // coordinates whose cubes overflow: no NaN twist
  auto huge = matched(scene_points(10, 9), scene_points(10, 10));
  for (auto& m : huge) m.x *= 1e110, m.y *= 1e110;
  ControlLawOptions moments;
  moments.features = VisualFeatures::kMoments;
  const ControlOutput h = compute_control(huge, moments);
  EXPECT_TRUE(h.twist.allFinite() && h.twist.isZero()) << h.twist.transpose();
  ControlLawOptions robust;
  robust.features = VisualFeatures::kSurface;
  robust.robust = RobustEstimator::kTukey;
  EXPECT_THROW(compute_control(matched(goal, goal), robust), std::invalid_argument);
}

// Issue 19: the M-estimators against hand-computed values. Residuals 1 2 3 4 100: median 3,
// deviations 2 1 0 1 97, their median 1, so sigma = 1.4826.
TEST(RobustWeights, TukeyAndHuberAgainstHandComputedValues) {
  const std::vector<double> r = {1, 2, 3, 4, 100};
  const auto t = robust_weights(RobustEstimator::kTukey, r, 1e-9);
  // c sigma = 4.6851 x 1.4826 = 6.9461; w = (1 - (d / 6.9461)^2)^2
  EXPECT_NEAR(t[0], 0.8410654988, 1e-9);
  EXPECT_NEAR(t[1], 0.9589776807, 1e-9);
  EXPECT_EQ(t[2], 1.0);
  EXPECT_NEAR(t[3], 0.9589776807, 1e-9);
  EXPECT_EQ(t[4], 0.0);
  const auto h = robust_weights(RobustEstimator::kHuber, r, 1e-9);
  // c sigma = 1.345 x 1.4826 = 1.9941; w = 1 within it, c sigma / d beyond
  EXPECT_NEAR(h[0], 0.9970485, 1e-9);
  EXPECT_EQ(h[1], 1.0);
  EXPECT_EQ(h[2], 1.0);
  EXPECT_EQ(h[3], 1.0);
  EXPECT_NEAR(h[4], 0.0205577010, 1e-9);
  for (double w : robust_weights(RobustEstimator::kNone, r, 1e-9)) EXPECT_EQ(w, 1.0);
  // equal residuals have no spread: the floor keeps them all in
  for (double w : robust_weights(RobustEstimator::kTukey, {0.5, 0.5, 0.5, 0.5}, 1e-4)) EXPECT_EQ(w, 1.0);
  EXPECT_EQ(parse_robust_estimator("huber"), RobustEstimator::kHuber);
  EXPECT_THROW(parse_robust_estimator("cauchy"), std::invalid_argument);
}

// The robust law against wrong matches: 40 points, the ids of 4 of them swapped in pairs. The
// plain law's task function is pulled off the true motion; the robust one (Tukey and Huber)
// recovers it and gives the swapped points (almost) no weight.
TEST(ControlLaw, RobustLawIgnoresSwappedMatches) {
  const auto goal = scene_points(40, 5);
  Vector6d offset;
  offset << 0.02, -0.01, 0.03, 0.02, -0.015, 0.01;
  const std::vector<Eigen::Vector3d> now = after_offset(goal, offset);
  ControlLawOptions p;
  p.model = InteractionModel::kCurrent;
  const ControlOutput clean = compute_control(matched(now, goal), p);
  auto wrong = matched(now, goal);
  for (int i : {3, 17}) {  // swap the current coordinates of (i, i+11): two wrong ids each
    std::swap(wrong[i].x, wrong[i + 11].x);
    std::swap(wrong[i].y, wrong[i + 11].y);
    std::swap(wrong[i].z, wrong[i + 11].z);
  }
  const ControlOutput plain = compute_control(wrong, p);
  const double plain_off = (plain.task - clean.task).norm() / clean.task.norm();
  EXPECT_GT(plain_off, 0.05) << "the swaps did not disturb the plain law";
  for (auto e : {RobustEstimator::kTukey, RobustEstimator::kHuber}) {
    p.robust = e;
    const ControlOutput robust = compute_control(wrong, p);
    const double off = (robust.task - clean.task).norm() / clean.task.norm();
    EXPECT_LT(off, 0.25 * plain_off) << to_string(e);
    for (int i : {3, 14, 17, 28}) EXPECT_LT(robust.weights[i], e == RobustEstimator::kTukey ? 0.05 : 0.5) << to_string(e) << " " << i;
    EXPECT_GT(robust.weights[0], 0.5);
  }
  // without outliers the robust law is the plain one, near enough
  p.robust = RobustEstimator::kTukey;
  const ControlOutput robust_clean = compute_control(matched(now, goal), p);
  EXPECT_LT((robust_clean.task - clean.task).norm(), 1e-3 * clean.task.norm());
}

TEST(ControlLaw, SaturationKeepsTheScrewDirection) {
  const auto goal = scene_points(40, 4);
  Vector6d offset;
  offset << 0.2, -0.1, 0.3, 0.3, -0.2, 0.1;
  const std::vector<Eigen::Vector3d> now = after_offset(goal, offset);
  ControlLawOptions p;
  p.model = InteractionModel::kDesired;
  p.gain = {2.0, 2.0, 0};
  const ControlOutput free = [&] {
    ControlLawOptions q = p;
    q.max_linear_mps = q.max_angular_radps = 1e9;
    return compute_control(matched(now, goal), q);
  }();
  p.max_linear_mps = 0.05;
  p.max_angular_radps = 0.05;
  const ControlOutput sat = compute_control(matched(now, goal), p);
  EXPECT_TRUE(sat.saturated);
  EXPECT_LE(sat.twist.head<3>().norm(), 0.05 + 1e-12);
  EXPECT_LE(sat.twist.tail<3>().norm(), 0.05 + 1e-12);
  EXPECT_NEAR(sat.twist.normalized().dot(free.twist.normalized()), 1.0, 1e-12);
}

TEST(ControlLaw, AdaptiveGain) {
  const Gain g{4.0, 0.4, 30.0};
  EXPECT_DOUBLE_EQ(g.at(0), 4.0);
  EXPECT_NEAR(g.at(1e6), 0.4, 1e-12);
  const double h = 1e-7;
  EXPECT_NEAR((g.at(h) - g.at(0)) / h, -30.0, 1e-3);  // slope lambda'0 at zero
  EXPECT_DOUBLE_EQ((Gain{0.5, 0.5, 0}.at(3.0)), 0.5);
}

TEST(ControlLaw, SafeStopWithTooFewPoints) {
  const auto pts = scene_points(3, 5);
  auto m = matched(pts, scene_points(3, 6));
  ControlLawOptions p;
  const ControlOutput out = compute_control(m, p);
  EXPECT_EQ(out.status, ControlStatus::kTooFewPoints);
  EXPECT_EQ(out.twist.norm(), 0.0);
  EXPECT_NE(out.reason.find("3 usable points"), std::string::npos) << out.reason;
  // a model whose depths are missing stops too
  for (auto& x : m) x.z.reset();
  m.insert(m.end(), m.begin(), m.end());
  p.model = InteractionModel::kCurrent;
  EXPECT_EQ(compute_control(m, p).status, ControlStatus::kNoDepth);
}

TEST(ControlLaw, NonFiniteInputIsRejectedNamingThePoint) {
  auto m = matched(scene_points(10, 7), scene_points(10, 8));
  m[4].x = std::nan("");
  try {
    compute_control(m, ControlLawOptions{});
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("(0, 4)"), std::string::npos) << e.what();
  }
  ControlLawOptions bad;
  bad.z_hat_m = -1;
  EXPECT_THROW(compute_control(matched(scene_points(10, 7), scene_points(10, 8)), bad), std::invalid_argument);
}

TEST(PseudoInverse, DropsTinySingularValues) {
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(4, 3);
  A(0, 0) = 1;
  A(1, 1) = 2;
  A(2, 2) = 1e-14;  // numerically rank 2
  const Eigen::MatrixXd P = pseudo_inverse(A, 1e-9);
  EXPECT_LT(P.cwiseAbs().maxCoeff(), 1.0 + 1e-12);
  EXPECT_NEAR(P(0, 0), 1.0, 1e-12);
  EXPECT_NEAR(P(1, 1), 0.5, 1e-12);
  EXPECT_EQ(P(2, 2), 0.0);
}

TEST(PseudoInverse, SolveAgreesWithTheExplicitPseudoInverse) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n;
  Eigen::MatrixXd A(40, 6);
  Eigen::VectorXd b(40);
  for (int i = 0; i < A.size(); ++i) A.data()[i] = n(rng);
  for (int i = 0; i < b.size(); ++i) b[i] = n(rng);
  double condition = 0;
  EXPECT_LT((pseudo_inverse_solve(A, b, 1e-9, &condition) - pseudo_inverse(A, 1e-9) * b).norm(), 1e-10);
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A);
  EXPECT_NEAR(condition, svd.singularValues()[0] / svd.singularValues()[5], 1e-9 * condition);
  A.col(5) = A.col(4);  // rank 5: both drop the null direction
  EXPECT_LT((pseudo_inverse_solve(A, b, 1e-6) - pseudo_inverse(A, 1e-6) * b).norm(), 1e-8);
}

TEST(MatchFeatures, OnlySpotsSeenInBoth) {
  const std::vector<Feature> now{{1, 1, 0.1, 0.2, 0.9}, {2, 2, 0.3, 0.4, std::nullopt}, {5, 5, 0, 0, 1.0}};
  const std::vector<Feature> goal{{2, 2, 0.31, 0.41, 0.8}, {1, 1, 0.11, 0.21, 0.7}, {7, 7, 0, 0, 1}};
  const auto m = match_features(now, goal);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0].row, 2);
  EXPECT_DOUBLE_EQ(m[0].x, 0.3);
  EXPECT_DOUBLE_EQ(m[0].x_star, 0.31);
  EXPECT_FALSE(m[0].z.has_value());
  EXPECT_DOUBLE_EQ(*m[1].z, 0.9);
}

// The interior of the matched set: the points whose four pattern neighbours are matched too.
// A 7 x 7 block has a 5 x 5 interior (25 of 49, over half): that is what serves. A hole inside
// takes its four neighbours out of the interior. A 5 x 5 block's 3 x 3 interior is under half:
// the block is mostly edge, and all of it serves; so too when the interior is under the count.
TEST(InteriorPoints, TheSpotsWhoseFourNeighboursAreMatchedWhenTheyAreHalfOfThem) {
  const auto block = [](int n, std::pair<int, int> hole = {-1, -1}) {
    std::vector<MatchedPoint> m;
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c)
        if (std::pair{r, c} != hole) m.push_back({r + 3, c + 5, 0.01 * c, 0.01 * r, 0.01 * c, 0.01 * r});
    return m;
  };
  const auto seven = interior_points(block(7), 0.5, 4);
  ASSERT_EQ(seven.size(), 25u);
  for (const auto& p : seven) {
    EXPECT_TRUE(p.row >= 4 && p.row <= 8 && p.col >= 6 && p.col <= 10) << p.row << "," << p.col;
  }
  EXPECT_EQ(interior_points(block(7, {3, 3}), 0.0, 4).size(), 20u) << "the hole and its four neighbours out";
  EXPECT_EQ(interior_points(block(5), 0.5, 4).size(), 25u) << "3 x 3 of 25 is under half: all serve";
  EXPECT_EQ(interior_points(block(5), 0.3, 4).size(), 9u);
  EXPECT_EQ(interior_points(block(5), 0.3, 10).size(), 25u) << "fewer than the law's count: all serve";
  EXPECT_TRUE(interior_points({}, 0.5, 4).empty());
}

TEST(Triangulation, RecoversTheDepthOfALitPoint) {
  calibration::ProjectorModel proj;
  proj.world_T_projector.translation() = Eigen::Vector3d(0.6, -0.2, 0.1);
  proj.world_T_projector.linear() = Eigen::AngleAxisd(-0.5, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Isometry3d wTc = Eigen::Isometry3d::Identity();
  for (auto [row, col] : {std::pair{3, 4}, std::pair{10, 10}, std::pair{17, 2}}) {
    // the lit point: along the projector ray at 1.2 m
    const Eigen::Vector3d X = proj.world_T_projector * (1.2 * proj.spot_ray(row, col));
    const Eigen::Vector2d xy(X.x() / X.z(), X.y() / X.z());
    const auto z = triangulate_depth(xy, row, col, proj, wTc);
    ASSERT_TRUE(z);
    EXPECT_NEAR(*z, X.z(), 1e-9);
  }
  // a ray parallel to the baseline cannot be triangulated
  calibration::ProjectorModel same = proj;
  same.world_T_projector = wTc;
  EXPECT_FALSE(triangulate_depth(Eigen::Vector2d(0, 0), 10, 10, same, wTc).has_value());
}

TEST(CameraIntrinsics, NormaliseInvertsTheDistortion) {
  const calibration::CameraIntrinsics k{800, 810, 320, 240, {-0.2, 0.05, 0.001, -0.002, 0.01}};
  for (const Eigen::Vector2d& x : {Eigen::Vector2d(0.1, -0.2), Eigen::Vector2d(-0.35, 0.25), Eigen::Vector2d(0, 0)}) {
    const double r2 = x.squaredNorm();
    const auto& d = k.distortion;
    const double radial = 1 + d[0] * r2 + d[1] * r2 * r2 + d[4] * r2 * r2 * r2;
    const Eigen::Vector2d xd(x.x() * radial + 2 * d[2] * x.x() * x.y() + d[3] * (r2 + 2 * x.x() * x.x()),
                             x.y() * radial + d[2] * (r2 + 2 * x.y() * x.y()) + 2 * d[3] * x.x() * x.y());
    const Eigen::Vector2d uv(k.fx * xd.x() + k.cx, k.fy * xd.y() + k.cy);
    EXPECT_LT((calibration::normalise(k, uv) - x).norm(), 1e-10);
  }
}

TEST(InteractionModel, ParsesItsNames) {
  EXPECT_EQ(parse_interaction_model("current"), InteractionModel::kCurrent);
  EXPECT_EQ(parse_interaction_model("desired-constant-depth"), InteractionModel::kDesiredConstantDepth);
  EXPECT_THROW(parse_interaction_model("Current"), std::invalid_argument);
}

TEST(ConditionedSubset, PicksWellSpreadPoints) {
  const auto pts = scene_points(200, 9);
  const auto m = matched(pts, pts);
  ControlLawOptions p;
  const auto subset = best_conditioned_subset(m, 8, p);
  ASSERT_EQ(subset.size(), 8u);
  const auto cond = [&](const std::vector<MatchedPoint>& s) {
    Eigen::VectorXd xy(2 * s.size()), Z(s.size());
    for (std::size_t i = 0; i < s.size(); ++i) xy[2 * i] = s[i].x_star, xy[2 * i + 1] = s[i].y_star, Z[i] = p.z_hat_m;
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(stacked_interaction_matrix(xy, Z));
    return svd.singularValues()[0] / svd.singularValues()[5];
  };
  const std::vector<MatchedPoint> first8(m.begin(), m.begin() + 8);
  EXPECT_LT(cond(subset), cond(first8));
}

}  // namespace
// issue 13: a runaway |e| is named once it passes ratio x its first value; 0 never trips
TEST(DivergenceWatch, TripsAboveRatioTimesTheFirstValueAndResets) {
  DivergenceWatch off;
  EXPECT_EQ(off.check(1.0), "");
  EXPECT_EQ(off.check(1e300), "");
  DivergenceWatch w(2);
  EXPECT_EQ(w.check(0.5), "");
  EXPECT_EQ(w.check(0.9), "");
  EXPECT_EQ(w.check(1.0), "");  // exactly twice: not above
  EXPECT_NE(w.check(1.01).find("diverging"), std::string::npos);
  w.reset();
  EXPECT_EQ(w.check(1.01), "");  // a new first value
  EXPECT_EQ(w.check(2.0), "");
}

}  // namespace control
