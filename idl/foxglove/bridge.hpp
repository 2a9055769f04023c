// The cell's topics, read over DDS as any client reads them, served live to Foxglove
// (`cellsim bridge`, `cellsim serve --foxglove`): the camera's images, camera_info, /tf, /joint_states, the
// /robot_description, the servo's status (|e|, its state), twist and decoded spots, the
// simulator's status, pose, spot truth and clock; and /servo/annotations (foxglove_msgs/
// ImageAnnotations: the decoded ids, the desired points, the error vectors) to draw over the
// image. Each sample is served as its CDR bytes with its ros2msg schema, as an MCAP recording
// holds it: a layout made for a recording works live.
#pragma once

#include <fastdds/dds/domain/DomainParticipant.hpp>

#include <memory>
#include <string>
#include <vector>

#include "foxglove/live_server.hpp"

namespace foxglove {

class Annotations;

class Bridge {
 public:
  // Subscribes to the cell's topics under ROS 2 namespace `ns` on `participant` and serves them
  // on a LiveServer made with `options`. Throws std::runtime_error naming the address when the
  // port cannot be listened on.
  Bridge(eprosima::fastdds::dds::DomainParticipant& participant, const std::string& ns, ServerOptions options);
  ~Bridge();
  int port() const { return server_->port(); }
  std::string url() const { return server_->url(); }
  std::size_t channels() const { return channels_; }
  ServerStats stats() const { return server_->stats(); }

 private:
  std::unique_ptr<LiveServer> server_;
  std::unique_ptr<Annotations> annotations_;  // /servo/annotations, drawn from /servo/spots and /sim/status
  std::vector<std::shared_ptr<void>> readers_;  // the DDS readers, each of its own type
  std::size_t channels_ = 0;
};

}  // namespace foxglove
