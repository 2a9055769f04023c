// What a ROS 2 tool sees of our participants (issue 9, items 18-19): every endpoint's
// USER_DATA carries its type hash, and ros_discovery_info names the node and its endpoints.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <mutex>
#include <thread>

#include "cell_msgsPubSubTypes.h"
#include "dds/ros_graph.hpp"
#include "dds/topics.hpp"
#include "sensor_msgsPubSubTypes.h"

namespace {

using namespace std::chrono_literals;

int test_domain() { return 200 + static_cast<int>(getpid() % 30); }

// Collects the USER_DATA of every writer discovered.
struct Discovery : eprosima::fastdds::dds::DomainParticipantListener {
  std::mutex m;
  std::map<std::string, std::string> user_data_by_topic;
  void on_publisher_discovery(eprosima::fastdds::dds::DomainParticipant*,
                              eprosima::fastrtps::rtps::WriterDiscoveryInfo&& info) override {
    std::lock_guard<std::mutex> l(m);
    const auto& ud = info.info.m_qos.m_userData;
    user_data_by_topic[info.info.topicName().to_string()] = std::string(ud.begin(), ud.end());
  }
};

TEST(RosGraph, TypeHashesInUserDataAndTheNodeOnRosDiscoveryInfo) {
  cell_dds::ParticipantOptions o;
  o.domain_id = test_domain();
  o.intraprocess = false;
  o.name = "graph_sub";
  Discovery listener;
  auto sub = cell_dds::make_participant(o);
  sub->set_listener(&listener, eprosima::fastdds::dds::StatusMask::none());
  std::mutex m;
  std::vector<rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_> infos;
  cell_dds::Reader<rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_PubSubType> graph(
      *sub, cell_dds::kRosDiscoveryTopic, cell_dds::reader_qos(cell_dds::Stream::kLatched),
      [&](rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_&& i) {
        std::lock_guard<std::mutex> l(m);
        infos.push_back(std::move(i));
      });

  o.name = "graph_pub";
  auto pub = cell_dds::make_participant(o);
  cell_dds::Writer<sensor_msgs::msg::dds_::Image_PubSubType> image(*pub, cell_dds::kImageTopic,
                                                                  cell_dds::writer_qos(cell_dds::Stream::kFrame));
  cell_dds::Writer<cell_msgs::msg::dds_::ServoStatus_PubSubType> status(*pub, cell_dds::kStatusTopic,
                                                                       cell_dds::writer_qos(cell_dds::Stream::kLatched));
  cell_dds::NodeAnnouncement node(*pub, "cellsim", {}, {image.guid(), status.guid()});

  const auto until = std::chrono::steady_clock::now() + 20s;
  while (std::chrono::steady_clock::now() < until) {
    {
      std::lock_guard<std::mutex> l(m), l2(listener.m);
      if (!infos.empty() && listener.user_data_by_topic.count(cell_dds::kImageTopic) &&
          listener.user_data_by_topic.count(cell_dds::kStatusTopic))
        break;
    }
    std::this_thread::sleep_for(20ms);
  }
  std::lock_guard<std::mutex> l(m), l2(listener.m);
  EXPECT_EQ(listener.user_data_by_topic[cell_dds::kImageTopic],
            "typehash=RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47;");
  EXPECT_EQ(listener.user_data_by_topic[cell_dds::kStatusTopic].rfind("typehash=RIHS01_", 0), 0u);
  ASSERT_FALSE(infos.empty());
  const auto& info = infos.back();
  EXPECT_EQ(info.gid().data(), cell_dds::NodeAnnouncement::gid_of(pub->guid()).data());
  ASSERT_EQ(info.node_entities_info_seq().size(), 1u);
  const auto& n = info.node_entities_info_seq()[0];
  EXPECT_EQ(n.node_name(), "cellsim");
  EXPECT_EQ(n.node_namespace(), "/");
  ASSERT_EQ(n.writer_gid_seq().size(), 2u);
  EXPECT_EQ(n.writer_gid_seq()[0].data(), cell_dds::NodeAnnouncement::gid_of(image.guid()).data());
  sub->set_listener(nullptr);
}

}  // namespace

namespace {

// Issue 21, item 2: latched and command writers say what they hold every 100 ms, not Fast
// DDS's default 3 s, so a late joiner that dropped their first send repairs at once
// (closed_loop.cyclone_late_joiner measures it with a Cyclone DDS client).
TEST(CellDds, LatchedWritersHeartbeatEvery100ms) {
  for (const auto s : {cell_dds::Stream::kLatched, cell_dds::Stream::kCommand}) {
    const auto q = cell_dds::writer_qos(s);
    EXPECT_EQ(q.reliable_writer_qos().times.heartbeatPeriod.seconds, 0);
    EXPECT_EQ(q.reliable_writer_qos().times.heartbeatPeriod.nanosec, 100'000'000u);
  }
  // the frame streams keep the default: every frame already carries its heartbeat
  EXPECT_EQ(cell_dds::writer_qos(cell_dds::Stream::kFrame).reliable_writer_qos().times.heartbeatPeriod.seconds, 3);
}

}  // namespace
