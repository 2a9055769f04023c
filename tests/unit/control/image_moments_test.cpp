// The image moments' interaction matrix against finite differences of the projection
// (issue 44: relative error <= 1e-4 at random poses), and the features' invariances.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <cmath>
#include <random>

#include "servo/control/image_moments.hpp"
#include "servo/control/surface_features.hpp"

namespace control {
namespace {

// points in the camera frame: a grid of `side` x `side` on a plane tilted by up to 35 deg, or
// on a bumpy surface, 0.5-1.5 m in front of the camera
std::vector<Eigen::Vector3d> scene(std::mt19937_64& rng, int side, bool bumpy) {
  std::uniform_real_distribution<double> U(-1, 1);
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(0.6 * U(rng), Eigen::Vector3d::UnitX()) *
                             Eigen::AngleAxisd(0.6 * U(rng), Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(3.1 * U(rng), Eigen::Vector3d::UnitZ()))
                                .toRotationMatrix();
  const Eigen::Vector3d centre(0.1 * U(rng), 0.1 * U(rng), 1.0 + 0.5 * U(rng));
  std::vector<Eigen::Vector3d> p;
  for (int i = 0; i < side; ++i)
    for (int j = 0; j < side; ++j) {
      // an irregular grid: no symmetry that would leave alpha undefined
      const double a = 0.3 * (i / (side - 1.0) - 0.5) + 0.01 * U(rng), b = 0.22 * (j / (side - 1.0) - 0.5) + 0.01 * U(rng);
      const double z = bumpy ? 0.05 * std::sin(9 * a) * std::cos(7 * b) : 0;
      p.push_back(centre + R * Eigen::Vector3d(a, b, z));
    }
  return p;
}

Eigen::VectorXd project(const std::vector<Eigen::Vector3d>& p) {
  Eigen::VectorXd xy(2 * static_cast<Eigen::Index>(p.size()));
  for (std::size_t k = 0; k < p.size(); ++k) xy.segment<2>(2 * static_cast<Eigen::Index>(k)) = p[k].head<2>() / p[k].z();
  return xy;
}

// the points as the camera sees them after moving for t with twist v (camera frame): a
// static point moves by -v - w x p; the second-order term cancels in a central difference
std::vector<Eigen::Vector3d> moved(const std::vector<Eigen::Vector3d>& p, const Vector6d& v, double t) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& q : p) out.push_back(q + t * (-v.head<3>() - v.tail<3>().cross(q)));
  return out;
}

TEST(ImageMoments, TheInteractionMatrixIsTheProjectionsDerivativeAtRandomPoses) {
  std::mt19937_64 rng(44);
  double worst = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const bool bumpy = trial % 2 == 1;
    const auto p = scene(rng, 4 + trial % 17, bumpy);
    const Eigen::VectorXd xy = project(p);
    Eigen::VectorXd Z(static_cast<Eigen::Index>(p.size()));
    for (std::size_t k = 0; k < p.size(); ++k) Z[static_cast<Eigen::Index>(k)] = p[k].z();
    const MomentScale scale{moment_area(xy) * (0.5 + trial % 3), 0.4 + 0.1 * (trial % 7)};
    const Matrix66 L = moment_interaction_matrix(xy, Z, scale);
    Matrix66 fd;
    const double h = 1e-6;
    for (int c = 0; c < 6; ++c) {
      const Vector6d v = Vector6d::Unit(c);
      fd.col(c) = moment_error(moment_features(project(moved(p, v, h)), scale),
                               moment_features(project(moved(p, v, -h)), scale)) / (2 * h);
    }
    for (int r = 0; r < 6; ++r) {
      const double rel = (fd.row(r) - L.row(r)).norm() / L.row(r).norm();
      worst = std::max(worst, rel);
      ASSERT_LE(rel, 1e-4) << "trial " << trial << ", feature " << r << "\nL\n" << L << "\nfinite differences\n" << fd;
    }
  }
  std::printf("worst relative error of a feature's row over 200 poses: %.2g\n", worst);
}

// the surface's features: the plane's normal and distance, three moments
TEST(SurfaceFeatures, TheInteractionMatrixIsTheProjectionsDerivativeAtRandomPoses) {
  std::mt19937_64 rng(45);
  double worst = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const auto p = scene(rng, 4 + trial % 17, false);
    const auto depths = [](const std::vector<Eigen::Vector3d>& q) {
      Eigen::VectorXd Z(static_cast<Eigen::Index>(q.size()));
      for (std::size_t k = 0; k < q.size(); ++k) Z[static_cast<Eigen::Index>(k)] = q[k].z();
      return Z;
    };
    const Eigen::VectorXd xy = project(p), Z = depths(p);
    const MomentScale scale{moment_area(xy), 0.5 + 0.1 * (trial % 7)};
    const Plane plane = fit_plane(xy, Z);
    const Matrix66 L = surface_interaction_matrix(xy, Z, plane, scale);
    Matrix66 fd;
    const double h = 1e-6;
    for (int c = 0; c < 6; ++c) {
      const Vector6d v = Vector6d::Unit(c);
      const auto ahead = moved(p, v, h), behind = moved(p, v, -h);
      Vector6d diff = surface_features(project(ahead), depths(ahead), scale) -
                      surface_features(project(behind), depths(behind), scale);
      diff[5] = std::remainder(diff[5], 3.14159265358979323846);
      fd.col(c) = diff / (2 * h);
    }
    for (int r = 0; r < 6; ++r) {
      const double rel = (fd.row(r) - L.row(r)).norm() / L.row(r).norm();
      worst = std::max(worst, rel);
      ASSERT_LE(rel, 1e-4) << "trial " << trial << ", feature " << r << "\nL\n" << L << "\nfinite differences\n" << fd;
    }
  }
  std::printf("worst relative error of a feature's row over 200 poses: %.2g\n", worst);
  EXPECT_THROW(fit_plane(Eigen::VectorXd::Ones(6), Eigen::VectorXd::Ones(3)), std::invalid_argument);  // one point thrice
}

// Issue 44: spots cast from a projector riding on the camera. A plane n . X = d (camera frame),
// rays X = o + mu b fixed in the camera frame; the camera moves by t (v, w), so the plane it sees
// becomes n - t w x n, d - t n . v (first order; the central difference cancels the second), and
// each spot slides along its ray to the new plane. riding_point_interaction_matrix, and the
// moments built on its rows, against central differences at 200 random planes and rigs.
struct RidingRig {
  Eigen::Vector3d n, o;
  double d = 1;
  std::vector<Eigen::Vector3d> rays;
};

RidingRig riding_rig(std::mt19937_64& rng, int spots) {
  std::uniform_real_distribution<double> U(-1, 1);
  RidingRig r;
  r.n = (Eigen::AngleAxisd(0.6 * U(rng), Eigen::Vector3d::UnitX()) * Eigen::AngleAxisd(0.6 * U(rng), Eigen::Vector3d::UnitY()))
            .toRotationMatrix() * Eigen::Vector3d::UnitZ();
  r.d = 1.0 + 0.4 * U(rng);
  r.o = Eigen::Vector3d(0.1 + 0.1 * U(rng), 0.05 * U(rng), 0.02 * U(rng));
  for (int k = 0; k < spots; ++k)  // towards points of an irregular patch about the optical axis
    r.rays.push_back((Eigen::Vector3d(0.25 * U(rng), 0.2 * U(rng), r.d) - r.o).normalized());
  return r;
}

// the spots' image points, and their depths, with the plane moved by t (v, w)
Eigen::VectorXd riding_image(const RidingRig& r, const Vector6d& v, double t, Eigen::VectorXd* Z = nullptr) {
  const Eigen::Vector3d n = r.n - t * v.tail<3>().cross(r.n);
  const double d = r.d - t * r.n.dot(v.head<3>());
  Eigen::VectorXd xy(2 * static_cast<Eigen::Index>(r.rays.size()));
  if (Z) Z->resize(static_cast<Eigen::Index>(r.rays.size()));
  for (std::size_t k = 0; k < r.rays.size(); ++k) {
    const Eigen::Vector3d X = r.o + (d - n.dot(r.o)) / n.dot(r.rays[k]) * r.rays[k];
    xy.segment<2>(2 * static_cast<Eigen::Index>(k)) = X.head<2>() / X.z();
    if (Z) (*Z)[static_cast<Eigen::Index>(k)] = X.z();
  }
  return xy;
}

TEST(RidingSpots, TheirInteractionMatricesAreTheProjectionsDerivativeAtRandomPlanes) {
  std::mt19937_64 rng(46);
  double worst_point = 0, worst_moment = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const RidingRig rig = riding_rig(rng, 12 + trial % 30);
    Eigen::VectorXd Z;
    const Eigen::VectorXd xy = riding_image(rig, Vector6d::Zero(), 0, &Z);
    std::vector<Matrix26> rows;
    for (Eigen::Index k = 0; k < Z.size(); ++k)
      rows.push_back(riding_point_interaction_matrix(xy[2 * k], xy[2 * k + 1], Z[k], rig.rays[static_cast<std::size_t>(k)], rig.n));
    const MomentScale scale{moment_area(xy), 0.9};
    const Matrix66 Lm = moment_interaction_matrix(xy, rows, scale);
    const double h = 1e-6;
    Eigen::MatrixXd fd(xy.size(), 6);
    Matrix66 fdm;
    for (int c = 0; c < 6; ++c) {
      const Eigen::VectorXd ahead = riding_image(rig, Vector6d::Unit(c), h), behind = riding_image(rig, Vector6d::Unit(c), -h);
      fd.col(c) = (ahead - behind) / (2 * h);
      fdm.col(c) = moment_error(moment_features(ahead, scale), moment_features(behind, scale)) / (2 * h);
    }
    for (Eigen::Index k = 0; k < Z.size(); ++k) {
      const Matrix26& L = rows[static_cast<std::size_t>(k)];
      const double rel = (fd.block<2, 6>(2 * k, 0) - L).norm() / L.norm();
      worst_point = std::max(worst_point, rel);
      ASSERT_LE(rel, 1e-4) << "trial " << trial << ", spot " << k << "\nL\n" << L << "\nfinite differences\n" << fd.block<2, 6>(2 * k, 0);
    }
    for (int r = 0; r < 6; ++r) {
      const double rel = (fdm.row(r) - Lm.row(r)).norm() / Lm.row(r).norm();
      worst_moment = std::max(worst_moment, rel);
      ASSERT_LE(rel, 1e-4) << "trial " << trial << ", moment " << r << "\nL\n" << Lm << "\nfinite differences\n" << fdm;
    }
    // one degree of freedom a spot: it moves along its epipolar line
    Eigen::JacobiSVD<Matrix26> svd(rows[0]);
    EXPECT_LT(svd.singularValues()[1], 1e-9 * svd.singularValues()[0]);
  }
  std::printf("worst relative error over 200 planes: a spot's rows %.2g, a moment's row %.2g\n", worst_point, worst_moment);
}

// x_n, y_n, a_n, alpha: a translation along the optical axis of a plane parallel to the image
// changes a_n alone; c_1 and c_2 do not change under a rotation about the optical axis
TEST(ImageMoments, TheFeaturesDecoupleAsDesigned) {
  std::mt19937_64 rng(7);
  std::vector<Eigen::Vector3d> p;
  std::uniform_real_distribution<double> U(-0.2, 0.2);
  for (int k = 0; k < 40; ++k) p.emplace_back(U(rng), 0.7 * U(rng), 1.0);
  const Eigen::VectorXd xy = project(p);
  const MomentScale scale{moment_area(xy), 1.0};
  const Vector6d s = moment_features(xy, scale);
  EXPECT_NEAR(s[2], 1.0, 1e-12) << "a_n = Z* at the desired points";
  Eigen::VectorXd Z = Eigen::VectorXd::Ones(40);
  const Matrix66 L = moment_interaction_matrix(xy, Z, scale);
  // rotation about z: x_n, y_n rotate, a_n, c_1, c_2 stay; alpha turns at -1 rad per rad
  EXPECT_NEAR(L(2, 5), 0, 1e-12);
  EXPECT_NEAR(L(4, 5), 0, 1e-12);
  EXPECT_NEAR(L(5, 5), 0, 1e-12);
  EXPECT_NEAR(L(3, 5), -1, 1e-12);
  // translation along z of a plane parallel to the image: a_n at -1 per metre (it is the depth)
  EXPECT_NEAR(L(2, 2), -1, 1e-12);
  EXPECT_NEAR(L(4, 2), 0, 1e-12);
  EXPECT_NEAR(L(5, 2), 0, 1e-12);
}

TEST(ImageMoments, AnOrientationIsComparedModuloPi) {
  Vector6d a = Vector6d::Zero(), b = Vector6d::Zero();
  a[3] = 1.5, b[3] = -1.5;  // 3 rad apart, 0.14 rad as orientations
  EXPECT_NEAR(moment_error(a, b)[3], 3.0 - 3.14159265358979323846, 1e-12);
  EXPECT_THROW(moment_features(Eigen::VectorXd::Zero(4), {}), std::invalid_argument);
  EXPECT_THROW(moment_features(Eigen::VectorXd::Ones(10), {}), std::invalid_argument);
  EXPECT_EQ(parse_visual_features("moments"), VisualFeatures::kMoments);
  EXPECT_THROW(parse_visual_features("surface!"), std::invalid_argument);
}

}  // namespace
}  // namespace control
