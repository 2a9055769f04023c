// The camera-projector geometry of one frame, beyond the paper (which has no epipolar check).
//
// The projector is static and calibrated (`cellsim calibration`), the camera's pose comes from
// the robot: so the projector ray through spot (row, col) is a known line in space, and its
// image in the camera is a known (epipolar) line. A spot that carries id (row, col) must lie on
// that line, within the centroid's error and the calibration's, and the two rays must meet in
// front of both devices. About 2 % of the pattern's ids pass at a given image point, and a
// third of those have the spot's colour: a cheap, strong filter against wrong ids, and a way
// to name a spot from its already identified neighbours.
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

#include "servo/calibration/camera_intrinsics.hpp"
#include "servo/calibration/projector_model.hpp"
#include "servo/pattern/window_table.hpp"

namespace vision {

class FittedEpipolarLines;

class EpipolarGeometry {
 public:
  // tolerance_px: how far from its epipolar line (camera pixels) a spot may be and keep its id
  EpipolarGeometry(const calibration::CameraIntrinsics& camera, const calibration::ProjectorModel& projector,
                   const Eigen::Isometry3d& world_T_camera, double tolerance_px);
  // Without the calibration: the lines of the frame's own fundamental matrix (FittedEpipolarLines
  // fitted with rank 2), each id's the line F (col, row, 1). No rays, so no front check. A line
  // is known as well as the spots it was fitted on only between them: `lines.spans()` says which
  // ids' lines are (trusted()), and the others are held to the tolerance where a rival's line is
  // weighed (decoder step 6's nearest free line).
  EpipolarGeometry(const calibration::CameraIntrinsics& camera, const FittedEpipolarLines& lines, int rows,
                   int cols, double tolerance_px);
  // whether id's line is known as well as the frame's spots lie on theirs (always, with the
  // calibration)
  bool trusted(const pattern::SpotId& id) const {
    return trusted_.empty() || trusted_[static_cast<std::size_t>(id.row) * cols_ + id.col] != 0;
  }

  // Normalised, undistorted coordinates of a pixel.
  Eigen::Vector2d normalise(double u, double v) const;
  // Distance in camera pixels from the normalised point xy to the image of the projector ray
  // of `id`; +infinity when the id is outside the pattern or the rays meet behind a device.
  // (inline: the decoder asks it of every window's spots and every candidate id)
  double residual_px(const Eigen::Vector2d& xy, const pattern::SpotId& id) const {
    constexpr double kNever = std::numeric_limits<double>::infinity();
    if (id.row < 0 || id.col < 0 || id.row >= rows_ || id.col >= cols_) return kNever;
    const std::size_t index = static_cast<std::size_t>(id.row) * cols_ + id.col;
    const double residual = line_distance_px(xy, index);
    // NaN-safe: only a passing point is triangulated
    if (!(residual <= tolerance_px_) || !front_check_) return residual;
    return meets_in_front(xy, index) ? residual : kNever;
  }
  // The distance alone, for the ids in row-major order (row * cols + col): no front check, no
  // bounds check. residual_px computes the same number first, so a point this puts beyond a
  // bound residual_px puts beyond it too: a search over many ids asks this, and residual_px
  // only of those within it.
  double line_distance_px(const Eigen::Vector2d& xy, std::size_t index) const {
    const Eigen::Vector3d& line = rays_[index].line;
    return std::abs(line.dot(Eigen::Vector3d(xy.x(), xy.y(), 1.0)));
  }
  bool consistent(const Eigen::Vector2d& xy, const pattern::SpotId& id) const {
    return residual_px(xy, id) <= tolerance_px_;
  }
  double tolerance_px() const { return tolerance_px_; }
  int rows() const { return rows_; }
  int cols() const { return cols_; }

 private:
  struct Ray {
    Eigen::Vector3d line;       // o x b, scaled so that |line . (x, y, 1)| is camera pixels
    Eigen::Vector3d direction;  // b: the projector ray's direction, camera frame
    double bb = 0, bo = 0;      // b.b and b.o (o: origin_), the front check's per ray
  };
  // The camera's ray s a (a = (x, y, 1)) and the projector's ray `index`, o + t b, meet (nearly)
  // in front of both devices: s, t > 0 at their closest points, each a numerator over
  // det = |a|^2 |b|^2 - (a.b)^2, positive where the rays are not parallel, so the numerators'
  // signs say it without the two divisions.
  bool meets_in_front(const Eigen::Vector2d& xy, std::size_t index) const {
    const Ray& ray = rays_[index];
    const Eigen::Vector3d a(xy.x(), xy.y(), 1.0);
    const double aa = a.dot(a), ab = a.dot(ray.direction), ao = a.dot(origin_);
    const double det = aa * ray.bb - ab * ab;
    if (det < 1e-12 * aa * ray.bb) return false;
    return ao * ray.bb - ab * ray.bo > 0 && ab * ao - aa * ray.bo > 0;
  }
  calibration::CameraIntrinsics camera_;
  Eigen::Vector3d origin_;  // the projector's centre, camera frame
  std::vector<Ray> rays_;   // row-major over the pattern
  int rows_ = 0, cols_ = 0;
  double tolerance_px_ = 3;
  bool front_check_ = true;
  std::vector<char> trusted_;
};

// Without the projector's calibration, the frame's own epipolar geometry: the fundamental
// matrix F between the camera's normalised coordinates x and the pattern's grid (col, row, 1),
// x' F p = 0, fitted to the frame's identified spots. The projector is a pinhole and its spots
// a regular grid on its image plane, so a grid position is its projector pixel up to an affine
// map that F absorbs; the camera's distortion is undone by its intrinsics. A spot's centre lies
// on the line F p of its id; a spill (its light past a silhouette, on the surface behind) or a
// spot split by a depth edge lies aside, as with the calibration.
class FittedEpipolarLines {
 public:
  // `xy`: the spots' normalised coordinates; `grid`: their ids' (col, row). Fitted by linear
  // least squares (Hartley's normalisation), then twice to the spots within `tolerance_px` of
  // their lines, each weighted so that its term is a pixel distance, not an algebraic one.
  // Fewer than 9 spots (one window's): nothing fitted (fitted() false).
  // Rank 2 (`rank2`): the last fit refined as F = U diag(1, s, 0) V' (Levenberg-Marquardt on the
  // same spots' pixel distances), so that every line passes through one epipole, the projector
  // centre's image, as a real projector's do. Where the lines serve to mark the frame's own spots
  // the linear fit serves (its lines lie 0.03 px from the cylinder's spots, whose near-critical
  // quadric lets truncation move them 0.4 px); where they name new spots, far from those fitted,
  // the linear fit's lines drift by pixels (the dark ham's wall spot 2.3 px off its own line), the
  // rank-2 fit's less (1.3 px), and spans() says where they are extrapolated (docs/decoding.md).
  FittedEpipolarLines(const std::vector<Eigen::Vector2d>& xy, const std::vector<Eigen::Vector2d>& grid,
                      double pixels_per_unit, double tolerance_px, bool rank2 = false);
  bool fitted() const { return fitted_; }
  // whether the grid position (col, row) lies in the convex hull of the ids the last fit used:
  // there its line is interpolated, beyond it extrapolated. Kept for a rank-2 fit only, whose
  // lines name new spots (false everywhere otherwise: marking a frame's own spots never asks)
  bool spans(const Eigen::Vector2d& grid) const;
  // distance in camera pixels from xy to the line of the id at grid position (col, row)
  double residual_px(const Eigen::Vector2d& xy, const Eigen::Vector2d& grid) const;
  const Eigen::Matrix3d& fundamental() const { return f_; }

 private:
  void refine_rank2(const std::vector<Eigen::Vector2d>& xy, const std::vector<Eigen::Vector2d>& grid,
                    const std::vector<double>& w);
  Eigen::Matrix3d f_ = Eigen::Matrix3d::Zero();
  std::vector<Eigen::Vector2d> hull_;  // counter-clockwise
  double pixels_ = 1;
  bool fitted_ = false;
};

}  // namespace vision
