#include "dds/ros_graph.hpp"

#include <cstring>

#include "dds/topics.hpp"

namespace cell_dds {

rmw_dds_common::msg::dds_::Gid_ NodeAnnouncement::gid_of(const eprosima::fastrtps::rtps::GUID_t& guid) {
  // the GUID's 12-byte prefix then its 4-byte entity id, as rmw_fastrtps builds a gid
  rmw_dds_common::msg::dds_::Gid_ g;
  std::array<std::uint8_t, 16> data{};
  std::memcpy(data.data(), guid.guidPrefix.value, 12);
  std::memcpy(data.data() + 12, guid.entityId.value, 4);
  g.data(data);
  return g;
}

NodeAnnouncement::NodeAnnouncement(eprosima::fastdds::dds::DomainParticipant& participant, const std::string& node_name,
                                   const std::vector<eprosima::fastrtps::rtps::GUID_t>& readers,
                                   const std::vector<eprosima::fastrtps::rtps::GUID_t>& writers,
                                   const std::string& node_namespace) {
  writer_ = std::make_unique<Writer<rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_PubSubType>>(
      participant, kRosDiscoveryTopic, writer_qos(Stream::kLatched));
  rmw_dds_common::msg::dds_::NodeEntitiesInfo_ node;
  node.node_namespace(node_namespace);
  node.node_name(node_name);
  for (const auto& r : readers) node.reader_gid_seq().push_back(gid_of(r));
  for (const auto& w : writers) node.writer_gid_seq().push_back(gid_of(w));
  rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_ info;
  info.gid(gid_of(participant.guid()));
  info.node_entities_info_seq().push_back(node);
  writer_->write(info);
}

}  // namespace cell_dds
