#include "servo/calibration/projector_model.hpp"

namespace calibration {

Eigen::Vector3d ProjectorModel::spot_ray(int row, int col) const {
  const double u = cx + (col - 0.5 * (cols - 1)) * spot_pitch_px;
  const double v = cy + (row - 0.5 * (rows - 1)) * spot_pitch_px;
  return Eigen::Vector3d((u - cx) / fx, (v - cy) / fy, 1.0).normalized();
}

}  // namespace calibration
