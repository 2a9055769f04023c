// The ROS 2 graph: a participant tells which nodes it holds and their endpoints on
// ros_discovery_info, as rmw implementations do, so `ros2 node list` shows /cellsim and
// /servo and `ros2 node info` their topics.
#pragma once

#include <fastdds/rtps/common/Guid.h>

#include <memory>
#include <string>
#include <vector>

#include "dds/endpoint.hpp"
#include "rmw_dds_commonPubSubTypes.h"

namespace cell_dds {

inline constexpr const char* kRosDiscoveryTopic = "ros_discovery_info";

// Publishes (latched) one node of `participant` with its endpoints; keep it alive as long as
// the node exists.
class NodeAnnouncement {
 public:
  NodeAnnouncement(eprosima::fastdds::dds::DomainParticipant& participant, const std::string& node_name,
                   const std::vector<eprosima::fastrtps::rtps::GUID_t>& readers,
                   const std::vector<eprosima::fastrtps::rtps::GUID_t>& writers,
                   const std::string& node_namespace = "/");

  static rmw_dds_common::msg::dds_::Gid_ gid_of(const eprosima::fastrtps::rtps::GUID_t& guid);

 private:
  std::unique_ptr<Writer<rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_PubSubType>> writer_;
};

}  // namespace cell_dds
