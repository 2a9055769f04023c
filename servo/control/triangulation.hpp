// Depth of a decoded spot by camera-projector triangulation (paper §4 and §6).
//
// What it needs, and from where:
//  - the camera ray: the spot's normalised image coordinates (its centroid and the camera's
//    calibrated intrinsics);
//  - the projector ray: the spot's decoded id (row, col) gives its centre on the projector's
//    image plane (the pattern's layout: pitch, centring) and the projector's calibrated
//    intrinsics turn it into a direction;
//  - the camera-projector pose cTp: the projector's calibrated pose in the world (it is
//    static) and the camera's pose in the world from the robot's kinematics: cTp = (wTc)^-1 wTp.
// The depth is the Z, in the camera frame, of the midpoint of the common perpendicular of the
// two rays (the least-squares point when noise keeps them from meeting).
#pragma once

#include <Eigen/Geometry>
#include <optional>

#include "servo/calibration/projector_model.hpp"

namespace control {

// Depth (m, camera frame) of the point seen at normalised (x, y) that the projector lit
// through spot (row, col). Empty when the rays are (nearly) parallel or the point would be
// behind either device.
std::optional<double> triangulate_depth(const Eigen::Vector2d& xy, int row, int col, const calibration::ProjectorModel& projector,
                                        const Eigen::Isometry3d& world_T_camera);

}  // namespace control
