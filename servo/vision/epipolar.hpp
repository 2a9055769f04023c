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
#include <vector>

#include "servo/calibration/camera_intrinsics.hpp"
#include "servo/calibration/projector_model.hpp"
#include "servo/pattern/window_table.hpp"

namespace vision {

class EpipolarGeometry {
 public:
  // tolerance_px: how far from its epipolar line (camera pixels) a spot may be and keep its id
  EpipolarGeometry(const calibration::CameraIntrinsics& camera, const calibration::ProjectorModel& projector,
                   const Eigen::Isometry3d& world_T_camera, double tolerance_px);

  // Normalised, undistorted coordinates of a pixel.
  Eigen::Vector2d normalise(double u, double v) const;
  // Distance in camera pixels from the normalised point xy to the image of the projector ray
  // of `id`; +infinity when the id is outside the pattern or the rays meet behind a device.
  double residual_px(const Eigen::Vector2d& xy, const pattern::SpotId& id) const;
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
  };
  calibration::CameraIntrinsics camera_;
  Eigen::Vector3d origin_;  // the projector's centre, camera frame
  std::vector<Ray> rays_;   // row-major over the pattern
  int rows_ = 0, cols_ = 0;
  double tolerance_px_ = 3;
};

}  // namespace vision
