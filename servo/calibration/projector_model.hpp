// The projector as calibrated (`cellsim calibration` writes it, servo/calibration/projector_calibration
// reads it): its pinhole, the pattern's layout on its image plane, and its pose in the world.
// The projector is static: the pose is the world's, the camera's comes from the robot.
#pragma once

#include <Eigen/Geometry>

namespace calibration {

struct ProjectorModel {
  double fx = 1500, fy = 1500, cx = 511.5, cy = 383.5;  // projector intrinsics (pixels)
  double spot_pitch_px = 15;                             // pattern layout on its image plane
  int rows = 20, cols = 20;                              // the pattern is centred on (cx, cy)
  Eigen::Isometry3d world_T_projector = Eigen::Isometry3d::Identity();

  // Unit direction, in the projector frame, of the ray through spot (row, col)'s centre.
  Eigen::Vector3d spot_ray(int row, int col) const;
};

}  // namespace calibration
