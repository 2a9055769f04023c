// The servo's side of the wire: DDS samples into the state machine's plain messages, and its
// replies into samples. One set of conversions for `servo run` (from DDS) and `servo replay`
// (from a recording), so that a replay feeds the state machine what the service fed it.
#pragma once

#include <Eigen/Geometry>
#include <optional>

#include "cell_msgs.h"
#include "geometry_msgs.h"
#include "sensor_msgs.h"
#include "servo/node/servo_state_machine.hpp"

namespace servo {

Stamp to_stamp(const builtin_interfaces::msg::dds_::Time_& t);
builtin_interfaces::msg::dds_::Time_ to_time(const Stamp& s);

// A frame's sim status; nullopt for LOADING, NOTICE and ENDED, which belong to no frame.
std::optional<SimFrameStatus> frame_status(const cell_msgs::msg::dds_::SimStatus_& s);
// The reported camera pose; nullopt when its orientation is not a unit quaternion.
std::optional<Eigen::Isometry3d> camera_pose(const geometry_msgs::msg::dds_::PoseStamped_& p);
CameraInfoMsg to_info(const sensor_msgs::msg::dds_::CameraInfo_& c);
// A view of the image's bytes (valid while `img` lives).
ImageView image_view(const sensor_msgs::msg::dds_::Image_& img);

geometry_msgs::msg::dds_::TwistStamped_ twist_message(const ServoReply& r);
cell_msgs::msg::dds_::ServoStatus_ status_message(const ServoReply& r);
cell_msgs::msg::dds_::DecodedSpots_ spots_message(const ServoReply& r);  // r.spots set

}  // namespace servo
