// The camera's lens: pinhole intrinsics plus plumb-bob (Brown-Conrady) distortion,
// the same model as OpenCV and ROS CameraInfo ("plumb_bob", D = k1 k2 p1 p2 k3).
#pragma once

#include <Eigen/Core>
#include <array>
#include <vector>

#include "sim/scenario/scenario.hpp"

namespace sim {

class CameraModel {
 public:
  CameraModel(const Intrinsics& intrinsics, const std::array<double, 5>& distortion);

  // Normalised (undistorted) coordinates -> distorted pixel.
  Eigen::Vector2d distort_to_pixel(const Eigen::Vector2d& xn) const;
  // Point in the camera frame -> distorted pixel. Precondition: z > 0.
  Eigen::Vector2d project(const Eigen::Vector3d& p_c) const { return distort_to_pixel(p_c.head<2>() / p_c.z()); }
  // Distorted pixel -> normalised coordinates (iterative inverse of the distortion).
  Eigen::Vector2d pixel_to_normalised(const Eigen::Vector2d& uv) const;

  // Normalised coordinates of every pixel centre, row-major (x, y interleaved): computed once
  // so the renderer casts each pixel's exact ray through the distorted lens.
  const std::vector<float>& pixel_rays() const { return pixel_rays_; }

  const Intrinsics& intrinsics() const { return k_; }
  const std::array<double, 5>& distortion() const { return d_; }
  bool has_distortion() const;

 private:
  Intrinsics k_;
  std::array<double, 5> d_;
  std::vector<float> pixel_rays_;
};

}  // namespace sim
