// The cell's topic map (docs/topics.md): names in ROS 2 form (rt/<name>) and the QoS each one
// needs. Both services, the tests and the tools take them from here.
#pragma once

#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <cstdint>
#include <string>

#include "builtin_interfaces.h"

namespace cell_dds {

inline constexpr const char* kImageTopic = "rt/camera/image_raw";
// the white reference frame (the projector casting white) taken at the pattern frame's pose,
// with the same stamp, sent before it: `cellsim serve --white-frame`, read by `servo run
// --white-frame` (docs/decoding.md, Appearance)
inline constexpr const char* kWhiteImageTopic = "rt/camera/white/image_raw";
inline constexpr const char* kCameraInfoTopic = "rt/camera/camera_info";
inline constexpr const char* kTwistTopic = "rt/servo/cmd_twist";
inline constexpr const char* kCameraPoseTopic = "rt/sim/camera_pose";
inline constexpr const char* kSpotTruthTopic = "rt/sim/spot_truth";
inline constexpr const char* kSpotsTopic = "rt/servo/spots";
inline constexpr const char* kStatusTopic = "rt/servo/status";
inline constexpr const char* kControlTopic = "rt/sim/control";
// the commands the simulator obeyed, in the order they took effect: the servo's commands (the
// simulator is the one reader of rt/sim/control, so a command published once reaches the run)
inline constexpr const char* kAcceptedTopic = "rt/sim/accepted";
inline constexpr const char* kClockTopic = "rt/clock";
inline constexpr const char* kSimStatusTopic = "rt/sim/status";
inline constexpr const char* kJointStatesTopic = "rt/joint_states";
inline constexpr const char* kTfTopic = "rt/tf";
inline constexpr const char* kRobotDescriptionTopic = "rt/robot_description";

// A cell's topic under a ROS 2 namespace: "rt/camera/image_raw" in namespace "cell2" is
// "rt/cell2/camera/image_raw" (ROS 2's /cell2/camera/image_raw). An empty namespace leaves
// the name as it is.
std::string namespaced(const std::string& ns, const char* topic);
// Checks a --namespace value as ROS 2 names are checked: segments of letters, digits and
// underscores, not starting with a digit, joined by '/', at most 64 characters; a leading
// '/' is dropped. Throws std::invalid_argument (one line) otherwise.
std::string checked_namespace(const std::string& ns);

// The most bytes a received sample of this DDS type ("cell_msgs::msg::dds_::ServoStatus_")
// may have on the wire (issue 40, item 4): a longer one is dropped before it is deserialised,
// so a peer's 10 MB string costs no memory past the transport. The largest legitimate image
// (4096 x 2304 rgba8), a URDF of 4 MB, 4 MB of spots; 64 kB for every small message.
std::uint32_t max_sample_bytes(const std::string& dds_type_name);

inline constexpr const char* kCameraFrame = "camera_optical";
inline constexpr const char* kWorldFrame = "world";

// What a topic's data is for, which decides its QoS:
enum class Stream {
  kFrame,    // one sample per camera frame (image, pose, truth, twist, spots): reliable, only the
             // newest kept, so lockstep loses nothing and realtime never queues stale frames
  kLatched,  // state a late joiner needs (camera info, servo status): reliable, transient local,
             // a heartbeat every kLatchedHeartbeatNs
  kCommand,  // commands (sim control): reliable, a few kept, none dropped
  kClock,    // the clock: best effort, newest only
};

// how often a latched or command writer says what it holds (a late joiner repairs from it)
inline constexpr std::uint32_t kLatchedHeartbeatNs = 100'000'000;
eprosima::fastdds::dds::DataWriterQos writer_qos(Stream s);
eprosima::fastdds::dds::DataReaderQos reader_qos(Stream s);

// Simulated time of frame k at period dt, as a ROS 2 stamp.
builtin_interfaces::msg::dds_::Time_ stamp_of(std::uint64_t frame, double dt_s);
std::uint64_t frame_of(const builtin_interfaces::msg::dds_::Time_& stamp, double dt_s);
double seconds(const builtin_interfaces::msg::dds_::Time_& stamp);

}  // namespace cell_dds
