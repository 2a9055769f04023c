// Where the camera may be: RESET poses outside are refused and a motion that would leave it
// stops the robot.
#pragma once

#include <Eigen/Core>

namespace sim {

struct Workspace {
  Eigen::Vector3d min_m = Eigen::Vector3d::Constant(-100.0);
  Eigen::Vector3d max_m = Eigen::Vector3d::Constant(100.0);
  bool contains(const Eigen::Vector3d& p) const {
    return (p.array() >= min_m.array()).all() && (p.array() <= max_m.array()).all();
  }
};

}  // namespace sim
