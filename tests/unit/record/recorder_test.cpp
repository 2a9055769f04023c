// The recorder (idl/record): schemas that are the types on the wire (by REP-2011 hash),
// the QoS each topic's writer offers, and messages that read back as the samples written.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>

#include "cell_msgsPubSubTypes.h"
#include "mcap/mcap_reader.hpp"
#include "record/recorder.hpp"
#include "sensor_msgsPubSubTypes.h"

namespace {

const std::vector<std::string> kWireTypes{
    "sensor_msgs/msg/Image",          "sensor_msgs/msg/CameraInfo",   "sensor_msgs/msg/JointState",
    "geometry_msgs/msg/TwistStamped", "geometry_msgs/msg/PoseStamped", "tf2_msgs/msg/TFMessage",
    "std_msgs/msg/String",            "rosgraph_msgs/msg/Clock",       "cell_msgs/msg/SimStatus",
    "cell_msgs/msg/ServoStatus",      "cell_msgs/msg/SimControl",      "cell_msgs/msg/DecodedSpots",
    "cell_msgs/msg/SpotTruthArray"};

// A ros2msg schema split at its "MSG: " lines and parsed again as .msg files hashes to the
// wire type's hash: the schema is the full definition, nothing missing, nothing different.
TEST(Recorder, EverySchemaParsedAsMsgTextHashesToItsWireType) {
  for (const auto& type : kWireTypes) {
    const std::string schema = cell_record::ros2msg_schema(type);
    const std::string rule = std::string(80, '=') + "\nMSG: ";
    cell_dds::TypeDescriptions parsed;
    std::string name = type, rest = schema;
    while (true) {
      const auto cut = rest.find(rule);
      const std::string text = rest.substr(0, cut);
      const auto slash = name.find('/');
      cell_dds::parse_msg_type(name.substr(0, slash), name.substr(name.rfind('/') + 1), text, parsed);
      if (cut == std::string::npos) break;
      rest = rest.substr(cut + rule.size());
      const auto eol = rest.find('\n');
      name = rest.substr(0, eol);
      rest = rest.substr(eol + 1);
    }
    EXPECT_EQ(cell_dds::type_hash(type, parsed), cell_dds::type_hash(type, cell_dds::project_type_descriptions()))
        << type << ":\n" << schema;
  }
}

TEST(Recorder, TheProjectsOwnTypesKeepTheirMsgTextWithConstants) {
  const std::string s = cell_record::ros2msg_schema("cell_msgs/msg/SimControl");
  EXPECT_NE(s.find("uint8 TEACH"), std::string::npos) << s;
  const std::string image = cell_record::ros2msg_schema("sensor_msgs/msg/Image");
  EXPECT_EQ(image.rfind("std_msgs/Header header\n", 0), 0u) << image;
  EXPECT_NE(image.find("MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"), std::string::npos) << image;
}

TEST(Recorder, OfferedQosIsTheTopicMapsQos) {
  const std::string latched = cell_record::offered_qos_yaml(cell_dds::Stream::kLatched);
  EXPECT_EQ(latched.rfind("- history: keep_last\n  depth: 1\n  reliability: reliable\n  durability: transient_local", 0), 0u)
      << latched;
  EXPECT_NE(cell_record::offered_qos_yaml(cell_dds::Stream::kClock).find("reliability: best_effort"), std::string::npos);
  EXPECT_NE(cell_record::offered_qos_yaml(cell_dds::Stream::kCommand).find("depth: 16"), std::string::npos);
}

template <typename PubSubType>
typename PubSubType::type decode(const mcap::MessageView& m) {
  PubSubType t;
  eprosima::fastrtps::rtps::SerializedPayload_t p(static_cast<std::uint32_t>(m.size));
  std::memcpy(p.data, m.data, m.size);
  p.length = static_cast<std::uint32_t>(m.size);
  typename PubSubType::type out;
  EXPECT_TRUE(t.deserialize(&p, &out));
  return out;
}

// Options for a new recording FILE in a folder of this test process's own
cell_record::RecordOptions new_recording(const std::string& folder, const std::string& file) {
  const auto dir = std::filesystem::temp_directory_path() / (folder + "_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  cell_record::RecordOptions o;
  o.file = dir / file;
  std::filesystem::remove(o.file);
  return o;
}

TEST(Recorder, MessagesReadBackAsTheSamplesRecordedAndImagesCanBeLeftOut) {
  for (const bool images : {true, false}) {
    cell_record::RecordOptions o = new_recording("recorder_test", images ? "with.mcap" : "without.mcap");
    o.images = images;
    cell_record::Recorder r(o, {{"scenario", "plane"}});
    sensor_msgs::msg::dds_::Image_ img;
    img.width(2);
    img.height(1);
    img.encoding("rgb8");
    img.step(6);
    img.data({1, 2, 3, 4, 5, 6});
    cell_msgs::msg::dds_::SimStatus_ st;
    st.frame(42);
    st.recent_refusals({"a refusal"});
    r.record<sensor_msgs::msg::dds_::Image_PubSubType>("rt/camera/image_raw", cell_dds::Stream::kFrame, img, 5);
    r.record<cell_msgs::msg::dds_::SimStatus_PubSubType>("rt/sim/status", cell_dds::Stream::kFrame, st, 6);
    const mcap::WriteSummary w = r.close();
    EXPECT_EQ(w.messages, images ? 2u : 1u);
    int read = 0;
    const mcap::ReadSummary s = mcap::read_mcap_file(o.file, [&](const mcap::Channel& c, const mcap::MessageView& m) {
      ++read;
      EXPECT_EQ(c.message_encoding, "cdr");
      if (c.topic == "/camera/image_raw") {
        EXPECT_EQ(decode<sensor_msgs::msg::dds_::Image_PubSubType>(m).data(), img.data());
        EXPECT_EQ(m.publish_time_ns, 5u);
      } else {
        EXPECT_EQ(c.topic, "/sim/status");
        const auto back = decode<cell_msgs::msg::dds_::SimStatus_PubSubType>(m);
        EXPECT_EQ(back.frame(), 42u);
        EXPECT_EQ(back.recent_refusals(), st.recent_refusals());
        EXPECT_EQ(c.metadata.at("topic_type_hash"),
                  cell_dds::type_hash("cell_msgs/msg/SimStatus", cell_dds::project_type_descriptions()));
      }
    });
    EXPECT_EQ(read, images ? 2 : 1);
    EXPECT_EQ(s.metadata.at("cellsim").at("scenario"), "plane");
    EXPECT_NE(r.describe(w).find(o.file.string()), std::string::npos);
  }
}

// A recording stopped by its size limit says so in the file: the twist of the frame whose
// image did not fit may be in it (servo replay counts such twists apart when it reads this)
TEST(Recorder, ARecordingStoppedAtItsSizeLimitSaysWhyInTheFile) {
  cell_record::RecordOptions o = new_recording("recorder_test", "limited.mcap");
  o.max_bytes = 64u << 10;
  cell_record::Recorder r(o, {{"scenario", "plane"}});
  cell_msgs::msg::dds_::SimStatus_ st;
  st.frame(7);
  sensor_msgs::msg::dds_::Image_ img;
  img.width(256);
  img.height(128);
  img.encoding("rgb8");
  img.step(768);
  img.data(std::vector<std::uint8_t>(768u * 128u, 9));  // 96 kB: past the limit
  r.record<cell_msgs::msg::dds_::SimStatus_PubSubType>("rt/sim/status", cell_dds::Stream::kFrame, st, 6);
  r.record<sensor_msgs::msg::dds_::Image_PubSubType>("rt/camera/image_raw", cell_dds::Stream::kFrame, img, 7);
  const mcap::WriteSummary w = r.close();
  EXPECT_TRUE(w.complete);
  EXPECT_EQ(w.messages, 1u);
  const mcap::ReadSummary s = mcap::read_mcap_file(o.file, nullptr);
  ASSERT_EQ(s.metadata.count(cell_record::kStoppedMetadata), 1u);
  EXPECT_NE(s.metadata.at(cell_record::kStoppedMetadata).at("reason").find("size limit"), std::string::npos);
  EXPECT_NE(r.describe(w).find("stopped at the size limit"), std::string::npos) << r.describe(w);
  // a recording that ran to its end has no such record
  o = new_recording("recorder_test", "whole.mcap");
  cell_record::Recorder whole(o, {{"scenario", "plane"}});
  whole.record<sensor_msgs::msg::dds_::Image_PubSubType>("rt/camera/image_raw", cell_dds::Stream::kFrame, img, 7);
  whole.close();
  EXPECT_EQ(mcap::read_mcap_file(o.file, nullptr).metadata.count(cell_record::kStoppedMetadata), 0u);
}

// Issue 40, item 10: --record-no-images leaves out the camera's topic exactly; under the valid
// namespace "camera/image_raw" every topic contains that text, and all were once left out.
TEST(Recorder, NoImagesLeavesOutTheImageTopicExactlyUnderAnyNamespace) {
  cell_record::RecordOptions o = new_recording("recorder_ns_test", "ns.mcap");
  o.images = false;
  const std::string ns = "camera/image_raw";
  o.image_topic = cell_dds::namespaced(ns, cell_dds::kImageTopic);
  cell_record::Recorder r(o, {});
  sensor_msgs::msg::dds_::Image_ img;
  cell_msgs::msg::dds_::SimStatus_ st;
  r.record<sensor_msgs::msg::dds_::Image_PubSubType>(cell_dds::namespaced(ns, cell_dds::kImageTopic),
                                                     cell_dds::Stream::kFrame, img, 1);
  r.record<cell_msgs::msg::dds_::SimStatus_PubSubType>(cell_dds::namespaced(ns, cell_dds::kSimStatusTopic),
                                                       cell_dds::Stream::kFrame, st, 2);
  const mcap::WriteSummary w = r.close();
  EXPECT_EQ(w.messages, 1u);
  EXPECT_EQ(w.topic_messages.count("/camera/image_raw/sim/status"), 1u);
}

}  // namespace
