// The projector as calibrated (`cellsim calibration` writes it, servo/calibration/projector_calibration
// reads it): its pinhole, the pattern's layout on its image plane, and its pose in the world.
// The projector is static (its pose the world's, the camera's from the robot), or rides on the
// camera (issue 44: its pose then the camera's, fixed whatever the robot does).
#pragma once

#include <Eigen/Geometry>
#include <optional>

namespace calibration {

struct ProjectorModel {
  double fx = 1500, fy = 1500, cx = 511.5, cy = 383.5;  // projector intrinsics (pixels)
  double spot_pitch_px = 15;                             // pattern layout on its image plane
  int rows = 20, cols = 20;                              // the pattern is centred on (cx, cy)
  Eigen::Isometry3d world_T_projector = Eigen::Isometry3d::Identity();
  // camera_T_projector when the projector rides on the camera (`mount: camera` in the file);
  // world_T_projector is then not used
  std::optional<Eigen::Isometry3d> on_camera;

  // The projector seen from the camera standing at world_T_camera.
  Eigen::Isometry3d camera_T_projector(const Eigen::Isometry3d& world_T_camera) const {
    return on_camera ? *on_camera : world_T_camera.inverse() * world_T_projector;
  }

  // Unit direction, in the projector frame, of the ray through spot (row, col)'s centre.
  Eigen::Vector3d spot_ray(int row, int col) const;
};

}  // namespace calibration
