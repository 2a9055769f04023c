// The controller's model of its camera: what calibration gives it (it may differ from the
// real lens). Pixel -> normalised coordinates, undistorted (plumb bob).
#pragma once

#include <Eigen/Core>
#include <array>

namespace calibration {

struct CameraIntrinsics {
  double fx = 800, fy = 800, cx = 319.5, cy = 239.5;
  std::array<double, 5> distortion{0, 0, 0, 0, 0};  // k1 k2 p1 p2 k3
};

// Normalised image coordinates (x, y) = (X/Z, Y/Z) of a distorted pixel: the features s.
Eigen::Vector2d normalise(const CameraIntrinsics& k, const Eigen::Vector2d& uv);

}  // namespace calibration
