// Issue 21, item 2, against the real processes: every reader and writer `cellsim serve` makes,
// the one `--autorun` adds on rt/sim/control and the one `--record` adds included, and every
// one of `servo run`, is named on ros_discovery_info, so
// `ros2 topic info -v` shows none of them as _NODE_NAME_UNKNOWN_. The endpoints are what
// discovery reports of cellsim's participant; the announcement is what a ROS 2 client reads.
#include <gtest/gtest.h>

#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <map>
#include <mutex>
#include <set>

#include "closed_loop/watcher.hpp"
#include "dds/ros_graph.hpp"

namespace {

using namespace closed_loop;
using eprosima::fastrtps::rtps::GUID_t;

// The endpoints discovered, by participant: topic of each reader and writer.
struct Endpoints : eprosima::fastdds::dds::DomainParticipantListener {
  std::mutex m;
  std::map<GUID_t, std::string> writers, readers;
  void on_publisher_discovery(eprosima::fastdds::dds::DomainParticipant*,
                              eprosima::fastrtps::rtps::WriterDiscoveryInfo&& info) override {
    std::lock_guard<std::mutex> l(m);
    writers[info.info.guid()] = info.info.topicName().to_string();
  }
  void on_subscriber_discovery(eprosima::fastdds::dds::DomainParticipant*,
                               eprosima::fastrtps::rtps::ReaderDiscoveryInfo&& info) override {
    std::lock_guard<std::mutex> l(m);
    readers[info.info.guid()] = info.info.topicName().to_string();
  }
};

std::set<std::string> gids_of(const std::vector<rmw_dds_common::msg::dds_::Gid_>& seq) {
  std::set<std::string> s;
  for (const auto& g : seq) s.emplace(g.data().begin(), g.data().end());
  return s;
}

// Starts `args` (a service whose node is `node_name`) and checks that every reader and writer
// discovery reports of its participant is named in its node's announcement; at least
// `min_writers` and `min_readers` must be found.
void expect_every_endpoint_named(const std::string& node_name, const std::vector<std::string>& args,
                                 std::size_t min_writers, std::size_t min_readers, const std::string& must_write = "") {
  const int domain = unique_domain(33);
  const std::string dir = tmp_dir("ros_graph");
  cell_dds::ParticipantOptions o;
  o.domain_id = domain;
  o.name = "graph_client";
  Endpoints found;
  auto client = cell_dds::make_participant(o);
  client->set_listener(&found, eprosima::fastdds::dds::StatusMask::none());
  std::mutex m;
  std::map<std::string, rmw_dds_common::msg::dds_::NodeEntitiesInfo_> nodes;  // by participant gid
  cell_dds::Reader<rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_PubSubType> graph(
      *client, cell_dds::kRosDiscoveryTopic, cell_dds::reader_qos(cell_dds::Stream::kLatched),
      [&](rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_&& i) {
        std::lock_guard<std::mutex> l(m);
        for (const auto& n : i.node_entities_info_seq())
          if (n.node_name() == node_name) nodes[std::string(i.gid().data().begin(), i.gid().data().end())] = n;
      });
  Process service(args, domain, dir + "/service.log");

  // the service's endpoints: those discovery reports outside the client (the graph's own writer aside)
  const auto endpoints = [&](std::map<GUID_t, std::string>& w, std::map<GUID_t, std::string>& r) {
    std::lock_guard<std::mutex> l(m), l2(found.m);
    w.clear();
    r.clear();
    for (const auto& [guid, topic] : found.writers)
      if (guid.guidPrefix != client->guid().guidPrefix && topic != cell_dds::kRosDiscoveryTopic) w[guid] = topic;
    for (const auto& [guid, topic] : found.readers)
      if (guid.guidPrefix != client->guid().guidPrefix && topic != cell_dds::kRosDiscoveryTopic) r[guid] = topic;
  };
  std::map<GUID_t, std::string> writers, readers;
  const bool all = [&] {
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(120);
    while (std::chrono::steady_clock::now() < until) {
      endpoints(writers, readers);
      bool announced = false;
      {
        std::lock_guard<std::mutex> l(m);
        announced = !nodes.empty();
      }
      if (announced && writers.size() >= min_writers && readers.size() >= min_readers) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
  }();
  ASSERT_TRUE(all) << writers.size() << " writers, " << readers.size() << " readers discovered; see " << dir;
  if (!must_write.empty()) {
    bool found_writer = false;
    for (const auto& [guid, topic] : writers) found_writer |= topic == must_write;
    EXPECT_TRUE(found_writer) << "no writer on " << must_write;
  }
  std::lock_guard<std::mutex> l(m);
  ASSERT_EQ(nodes.size(), 1u);
  const auto& node = nodes.begin()->second;
  const std::set<std::string> named_writers = gids_of(node.writer_gid_seq()), named_readers = gids_of(node.reader_gid_seq());
  const auto key = [](const GUID_t& g) {
    const auto gid = cell_dds::NodeAnnouncement::gid_of(g).data();
    return std::string(gid.begin(), gid.end());
  };
  for (const auto& [guid, topic] : writers)
    EXPECT_EQ(named_writers.count(key(guid)), 1u) << node_name << "'s writer on " << topic << " is not named";
  for (const auto& [guid, topic] : readers)
    EXPECT_EQ(named_readers.count(key(guid)), 1u) << node_name << "'s reader on " << topic << " is not named";
  client->set_listener(nullptr);
}

TEST(RosGraphLoop, EveryEndpointOfCellsimWithAutorunIsNamedOnRosDiscoveryInfo) {
  // 10 writers with --autorun (image, camera_info, pose, sim status, truth, clock, joints, tf,
  // robot_description, control) and 3 readers (twist, control, servo status)
  expect_every_endpoint_named("cellsim", {kBin + "cellsim", "serve", kSrc + "/sim/scenarios/plane.yaml", "--autorun"},
                              10, 3, cell_dds::kControlTopic);
}

TEST(RosGraphLoop, EveryEndpointOfARecordingCellsimIsNamedOnRosDiscoveryInfo) {
  // --record adds a reader of the servo's decoded spots
  expect_every_endpoint_named("cellsim",
                              {kBin + "cellsim", "serve", kSrc + "/sim/scenarios/plane.yaml", "--record",
                               tmp_dir("ros_graph_record") + "/run.mcap", "--record-no-images"},
                              9, 4, "");
}

TEST(RosGraphLoop, EveryEndpointOfTheServoIsNamedOnRosDiscoveryInfo) {
  // 3 writers (twist, spots, status) and 5 readers (image, camera_info, pose, sim status, control)
  expect_every_endpoint_named(
      "servo", {kBin + "servo", "run", "--pattern", kSrc + "/servo/pattern/data/marray_20x20_k3_w3.txt"}, 3, 5,
      cell_dds::kTwistTopic);
}

}  // namespace

namespace {

// Issue 21, item 2: a client that joins a running cell gets the node names at once. It joins
// once cellsim is up and announced (an earlier client has heard it), and waits, bounded, for
// cellsim's node on ros_discovery_info; the delay is printed, not asserted (loaded machines).
// What makes it prompt is the latched writers' heartbeat period (CellDds.LatchedWritersHeartbeat).
TEST(RosGraphLoop, ALateJoinerGetsTheNodeNames) {
  const int domain = unique_domain(34);
  const std::string dir = tmp_dir("late_joiner");
  Watcher first(domain);
  Process sim({kBin + "cellsim", "serve", kSrc + "/sim/scenarios/plane.yaml"}, domain, dir + "/sim.log");
  ASSERT_TRUE(first.wait_until_cellsim_heard()) << "see " << dir;
  cell_dds::ParticipantOptions o;
  o.domain_id = domain;
  o.name = "late_joiner";
  const auto joined = std::chrono::steady_clock::now();
  auto late = cell_dds::make_participant(o);
  std::mutex m;
  std::optional<std::chrono::steady_clock::time_point> named;
  cell_dds::Reader<rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_PubSubType> graph(
      *late, cell_dds::kRosDiscoveryTopic, cell_dds::reader_qos(cell_dds::Stream::kLatched),
      [&](rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_&& i) {
        for (const auto& n : i.node_entities_info_seq())
          if (n.node_name() == "cellsim") {
            std::lock_guard<std::mutex> l(m);
            if (!named) named = std::chrono::steady_clock::now();
          }
      });
  const auto until = joined + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < until) {
    {
      std::lock_guard<std::mutex> l(m);
      if (named) break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  std::lock_guard<std::mutex> l(m);
  ASSERT_TRUE(named) << "no node names on ros_discovery_info within 60 s of joining";
  std::printf("late joiner: cellsim's node name after %.0f ms\n",
              std::chrono::duration<double, std::milli>(*named - joined).count());
}

}  // namespace
