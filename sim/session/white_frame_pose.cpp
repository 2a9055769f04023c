#include "sim/session/white_frame_pose.hpp"

#include "sim/geometry/se3.hpp"

namespace sim {

Eigen::Isometry3d WhiteFramePose::at(const FrameOrder& f) {
  if (f.repeat && last_ && last_->first == f.index) return last_->second;
  // the camera came from the frame before's pose by the twist answering it (a frame that
  // applies a twist after one that applied one): the white frame is taken on that way, the
  // lead's share of it back from this frame's pose
  const bool came = moving_from_.has_value() && f.applies_twist;
  const Eigen::Isometry3d pose =
      came && lead_ > 0 ? interpolate(f.scene_world_T_camera, *moving_from_, lead_) : f.scene_world_T_camera;
  if (f.applies_twist) moving_from_ = f.scene_world_T_camera;
  else moving_from_.reset();
  last_ = std::make_pair(f.index, pose);
  return pose;
}

}  // namespace sim
