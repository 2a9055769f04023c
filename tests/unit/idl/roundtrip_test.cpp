// Every IDL type goes out of one DDS participant and comes back in another, over the real
// transport (intraprocess delivery off), with the ROS 2 wire type names.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <thread>

#include "cell_msgsPubSubTypes.h"
#include "dds/participant.hpp"
#include "geometry_msgsPubSubTypes.h"
#include "rosgraph_msgsPubSubTypes.h"
#include "sensor_msgsPubSubTypes.h"

using namespace eprosima::fastdds::dds;

namespace {

// A domain of this process's own, so parallel test runs never see each other.
int test_domain() { return 100 + static_cast<int>(getpid() % 100); }

class RoundTrip : public ::testing::Test {
 protected:
  void SetUp() override {
    cell_dds::ParticipantOptions o;
    o.domain_id = test_domain();
    o.intraprocess = false;
    o.name = "roundtrip_pub";
    pub_ = cell_dds::make_participant(o);
    o.name = "roundtrip_sub";
    sub_ = cell_dds::make_participant(o);
  }

  template <typename PubSubType, typename T>
  T round_trip(const std::string& topic_name, const T& sent, const std::string& expected_type_name) {
    TypeSupport type_pub(new PubSubType());
    TypeSupport type_sub(new PubSubType());
    EXPECT_EQ(type_pub.get_type_name(), expected_type_name);
    cell_dds::register_type(*pub_, type_pub);
    cell_dds::register_type(*sub_, type_sub);
    Topic* tp = pub_->create_topic(topic_name, type_pub.get_type_name(), TOPIC_QOS_DEFAULT);
    Topic* ts = sub_->create_topic(topic_name, type_sub.get_type_name(), TOPIC_QOS_DEFAULT);
    EXPECT_TRUE(tp && ts);
    DataWriterQos wq = DATAWRITER_QOS_DEFAULT;
    wq.reliability().kind = RELIABLE_RELIABILITY_QOS;
    wq.durability().kind = TRANSIENT_LOCAL_DURABILITY_QOS;
    wq.history().kind = KEEP_LAST_HISTORY_QOS;
    wq.history().depth = 1;
    DataReaderQos rq = DATAREADER_QOS_DEFAULT;
    rq.reliability().kind = RELIABLE_RELIABILITY_QOS;
    rq.durability().kind = TRANSIENT_LOCAL_DURABILITY_QOS;
    rq.history().kind = KEEP_LAST_HISTORY_QOS;
    rq.history().depth = 1;
    DataWriter* writer = pub_->create_publisher(PUBLISHER_QOS_DEFAULT)->create_datawriter(tp, wq);
    DataReader* reader = sub_->create_subscriber(SUBSCRIBER_QOS_DEFAULT)->create_datareader(ts, rq);
    EXPECT_TRUE(writer && reader);

    // bounded wait for discovery, then one sample
    PublicationMatchedStatus st;
    for (int i = 0; i < 200; ++i) {
      writer->get_publication_matched_status(st);
      if (st.current_count > 0) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    EXPECT_GT(st.current_count, 0) << topic_name << ": reader never matched";
    T copy = sent;
    EXPECT_TRUE(writer->write(&copy));
    T received;
    SampleInfo info;
    EXPECT_TRUE(reader->wait_for_unread_message(eprosima::fastrtps::Duration_t(10, 0))) << topic_name;
    EXPECT_EQ(reader->take_next_sample(&received, &info), ReturnCode_t::RETCODE_OK) << topic_name;
    return received;
  }

  cell_dds::ParticipantPtr pub_, sub_;
};

std_msgs::msg::dds_::Header_ header(int sec, unsigned nsec, const std::string& frame) {
  std_msgs::msg::dds_::Header_ h;
  h.stamp().sec(sec);
  h.stamp().nanosec(nsec);
  h.frame_id(frame);
  return h;
}

TEST_F(RoundTrip, ImageAtVgaSize) {
  sensor_msgs::msg::dds_::Image_ img;
  img.header(header(12, 40000000, "camera_optical"));
  img.height(480);
  img.width(640);
  img.encoding("rgb8");
  img.is_bigendian(0);
  img.step(640 * 3);
  img.data().resize(640 * 480 * 3);
  for (std::size_t i = 0; i < img.data().size(); ++i) img.data()[i] = static_cast<uint8_t>(i * 31 + 7);
  const auto got = round_trip<sensor_msgs::msg::dds_::Image_PubSubType>("rt/test/image_raw", img,
                                                                        "sensor_msgs::msg::dds_::Image_");
  EXPECT_TRUE(got == img);
}

TEST_F(RoundTrip, CameraInfo) {
  sensor_msgs::msg::dds_::CameraInfo_ ci;
  ci.header(header(1, 2, "camera_optical"));
  ci.height(480);
  ci.width(640);
  ci.distortion_model("plumb_bob");
  ci.d({-0.1, 0.01, 0.001, -0.002, 0.0});
  ci.k({800, 0, 319.5, 0, 800, 239.5, 0, 0, 1});
  ci.r({1, 0, 0, 0, 1, 0, 0, 0, 1});
  ci.p({800, 0, 319.5, 0, 0, 800, 239.5, 0, 0, 0, 1, 0});
  const auto got = round_trip<sensor_msgs::msg::dds_::CameraInfo_PubSubType>("rt/test/camera_info", ci,
                                                                             "sensor_msgs::msg::dds_::CameraInfo_");
  EXPECT_TRUE(got == ci);
}

TEST_F(RoundTrip, TwistStamped) {
  geometry_msgs::msg::dds_::TwistStamped_ t;
  t.header(header(3, 4, "camera_optical"));
  t.twist().linear().x(0.1);
  t.twist().linear().y(-0.2);
  t.twist().linear().z(0.3);
  t.twist().angular().x(-0.01);
  t.twist().angular().y(0.02);
  t.twist().angular().z(-0.03);
  const auto got = round_trip<geometry_msgs::msg::dds_::TwistStamped_PubSubType>(
      "rt/test/cmd_twist", t, "geometry_msgs::msg::dds_::TwistStamped_");
  EXPECT_TRUE(got == t);
}

TEST_F(RoundTrip, PoseStamped) {
  geometry_msgs::msg::dds_::PoseStamped_ p;
  p.header(header(5, 6, "world"));
  p.pose().position().x(1.0);
  p.pose().position().z(0.9);
  p.pose().orientation().w(1.0);
  const auto got = round_trip<geometry_msgs::msg::dds_::PoseStamped_PubSubType>(
      "rt/test/camera_pose", p, "geometry_msgs::msg::dds_::PoseStamped_");
  EXPECT_TRUE(got == p);
}

TEST_F(RoundTrip, Clock) {
  rosgraph_msgs::msg::dds_::Clock_ c;
  c.clock().sec(42);
  c.clock().nanosec(999999999);
  const auto got = round_trip<rosgraph_msgs::msg::dds_::Clock_PubSubType>("rt/test/clock", c,
                                                                          "rosgraph_msgs::msg::dds_::Clock_");
  EXPECT_TRUE(got == c);
}

TEST_F(RoundTrip, DecodedSpots) {
  cell_msgs::msg::dds_::DecodedSpots_ s;
  s.header(header(7, 8, "camera_optical"));
  s.detected(399);
  s.decode_time_ms(1.25);
  for (int i = 0; i < 370; ++i) {
    cell_msgs::msg::dds_::Spot_ spot;
    spot.row(static_cast<int16_t>(i / 20));
    spot.col(static_cast<int16_t>(i % 20));
    spot.u(10.5 + i);
    spot.v(20.25 + i);
    s.spots().push_back(spot);
  }
  const auto got = round_trip<cell_msgs::msg::dds_::DecodedSpots_PubSubType>("rt/test/spots", s,
                                                                             "cell_msgs::msg::dds_::DecodedSpots_");
  EXPECT_TRUE(got == s);
}

TEST_F(RoundTrip, SpotTruth) {
  cell_msgs::msg::dds_::SpotTruthArray_ s;
  s.header(header(9, 10, "camera_optical"));
  cell_msgs::msg::dds_::SpotTruth_ t;
  t.row(3);
  t.col(4);
  t.visible(true);
  t.u(100.125);
  t.v(200.5);
  t.depth_m(0.9);
  s.spots().push_back(t);
  const auto got = round_trip<cell_msgs::msg::dds_::SpotTruthArray_PubSubType>(
      "rt/test/spot_truth", s, "cell_msgs::msg::dds_::SpotTruthArray_");
  EXPECT_TRUE(got == s);
}

TEST_F(RoundTrip, ServoStatus) {
  cell_msgs::msg::dds_::ServoStatus_ s;
  s.header(header(11, 12, "camera_optical"));
  s.state(cell_msgs::msg::dds_::ServoStatus_Constants::CONVERGED);
  s.iteration(87);
  s.error_norm(1.5e-5);
  s.decoded(370);
  s.matched(361);
  s.reason("error below threshold");
  const auto got = round_trip<cell_msgs::msg::dds_::ServoStatus_PubSubType>("rt/test/status", s,
                                                                            "cell_msgs::msg::dds_::ServoStatus_");
  EXPECT_TRUE(got == s);
}

TEST_F(RoundTrip, SimControl) {
  cell_msgs::msg::dds_::SimControl_ c;
  c.header(header(13, 14, ""));
  c.command(cell_msgs::msg::dds_::SimControl_Constants::STEP);
  c.argument("");
  c.steps(5);
  const auto got = round_trip<cell_msgs::msg::dds_::SimControl_PubSubType>("rt/test/control", c,
                                                                           "cell_msgs::msg::dds_::SimControl_");
  EXPECT_TRUE(got == c);
}

}  // namespace
