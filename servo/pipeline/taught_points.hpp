// The points the taught spots light, held against every later frame (issue 41: the spills
// that lie on their epipolar lines kept from the law).
//
// The paper's cell has a static projector and a static scene: the point of the surface a spot
// lights is a fixed point of the world, wherever the camera goes. Triangulated once, at
// teaching, it says where that id's spot must lie in every later frame: its projection from the
// camera's pose. A spot named with the id elsewhere is not that spot's centre: a spill of its
// light past a silhouette, or the visible part of a spot split by a depth edge, that lies along
// its id's line (a shift along the line is a change of depth, which the line cannot see). It
// is no feature of the law. The limit follows the frame as the decoder's grown limit does
// (vision::GrownLimit, no number of its own): a multiple of the median residual of the frame's
// checked spots, so a calibration error or a pose's latency, which moves every spot alike,
// loosens it rather than emptying the law. With a projector riding on the camera the lit
// points move with it: there is nothing to hold them to (ServoPipeline refuses the option).
#pragma once

#include <Eigen/Geometry>
#include <vector>

#include "servo/control/control_law.hpp"
#include "servo/vision/spot_decoder.hpp"

namespace servo {

struct TaughtPoint {
  int row = 0, col = 0;
  Eigen::Vector3d world = Eigen::Vector3d::Zero();  // the lit point (m, world frame)
};

// The world points of the features that have a depth, seen from `world_T_camera`, by id.
std::vector<TaughtPoint> taught_points(const std::vector<control::Feature>& features,
                                       const Eigen::Isometry3d& world_T_camera);

struct TaughtCheck {
  std::vector<char> off;  // per feature: farther than the limit from its taught point's projection
  int checked = 0;        // the features with a taught point
  int kept_out = 0;       // of them, off
  double limit_px = 0;    // this frame's limit (infinite with fewer than a window's 9 checked)
};

// Each feature against the projection of its id's taught point from `world_T_camera`, in
// pixels (the normalised distance scaled by the focal lengths); a feature whose id was not
// taught is not checked. A taught point behind the camera is off.
TaughtCheck check_taught(const std::vector<control::Feature>& features, const std::vector<TaughtPoint>& taught,
                         const Eigen::Isometry3d& world_T_camera, double fx, double fy, const vision::GrownLimit& limit);

}  // namespace servo
