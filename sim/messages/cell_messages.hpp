// The cell's side of the wire: what `cellsim serve` publishes for a frame order, built in one
// place for the service (which writes them on DDS) and for a recording of an in-process
// experiment (which writes them into an MCAP file, as the service's recorder would).
#pragma once

#include <opencv2/core/mat.hpp>

#include <deque>
#include <string>

#include "cell_msgs.h"
#include "geometry_msgs.h"
#include "rosgraph_msgs.h"
#include "sensor_msgs.h"
#include "std_msgs.h"
#include "tf2_msgs.h"
#include "sim/session/cell_state_machine.hpp"
#include "sim/render/renderer.hpp"

namespace sim::wire {

using Stamp = builtin_interfaces::msg::dds_::Time_;

// rt/sim/status: the frame's state and the session's counts, latest refusals, end
cell_msgs::msg::dds_::SimStatus_ frame_status(const sim::FrameOrder& f, const sim::CellStateMachine& cell,
                                              const Stamp& stamp, const std::deque<std::string>& refusals);
// a status that belongs to no frame (LOADING, NOTICE, ENDED), stamped with the next frame's
cell_msgs::msg::dds_::SimStatus_ status_between_frames(std::uint8_t state, const sim::CellStateMachine& cell,
                                                       const std::deque<std::string>& refusals);
// rt/sim/camera_pose: what the robot reports (not the truth when the scenario has errors)
geometry_msgs::msg::dds_::PoseStamped_ camera_pose(const sim::FrameOrder& f, const Stamp& stamp);
// rt/tf (world -> base -> each link -> camera optical frame); rt/joint_states when there is an arm
tf2_msgs::msg::dds_::TFMessage_ transforms(const sim::Scenario& s, const sim::FrameOrder& f, const Stamp& stamp);
bool has_joints(const sim::Scenario& s, const sim::FrameOrder& f);
sensor_msgs::msg::dds_::JointState_ joint_state(const sim::FrameOrder& f, const Stamp& stamp);
// rt/sim/spot_truth: every spot's truth in the image
cell_msgs::msg::dds_::SpotTruthArray_ spot_truth(const sim::Cell& cell, const sim::FrameOrder& f, const Stamp& stamp);
sensor_msgs::msg::dds_::Image_ image(const cv::Mat& rgb, const Stamp& stamp);
rosgraph_msgs::msg::dds_::Clock_ clock(const Stamp& stamp);
// rt/camera/camera_info: the intrinsics as calibration gave them (off by the scenario's errors)
sensor_msgs::msg::dds_::CameraInfo_ camera_info(const sim::Scenario& s, const Stamp& stamp);
// rt/robot_description: the URDF (empty without an arm)
std_msgs::msg::dds_::String_ description(const sim::Scenario& s);
// rt/sim/control
cell_msgs::msg::dds_::SimControl_ control(const sim::CommandMsg& c);

}  // namespace sim::wire
