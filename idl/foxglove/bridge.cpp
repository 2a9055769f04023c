#include "foxglove/bridge.hpp"

#include "foxglove/annotations.hpp"

#include <functional>

#include "cell_msgsPubSubTypes.h"
#include "foxglove_msgsPubSubTypes.h"
#include "dds/endpoint.hpp"
#include "dds/topics.hpp"
#include "dds/type_hash.hpp"
#include "geometry_msgsPubSubTypes.h"
#include "record/recorder.hpp"
#include "rosgraph_msgsPubSubTypes.h"
#include "sensor_msgsPubSubTypes.h"
#include "std_msgsPubSubTypes.h"
#include "tf2_msgsPubSubTypes.h"

namespace foxglove {

namespace {

// A sample's CDR bytes, as the wire carries them, to the subscribers of channel `index` (none:
// the sample is not serialised).
template <class PubSubType>
void forward(LiveServer& server, std::size_t index, const typename PubSubType::type& sample) {
  if (!server.subscribed(index)) return;
  PubSubType type;
  auto& m = const_cast<typename PubSubType::type&>(sample);  // Fast DDS 2's serialize takes void*
  eprosima::fastrtps::rtps::SerializedPayload_t payload(type.getSerializedSizeProvider(&m)());
  if (type.serialize(&m, &payload)) server.publish(index, cell_record::wall_ns(), payload.data, payload.length);
}

// The topics, their channels, and how to start each one's reader once the server is up.
class Topics {
 public:
  Topics(eprosima::fastdds::dds::DomainParticipant& p, std::string ns) : p_(p), ns_(std::move(ns)) {}

  // a topic read over DDS and served; `hook` sees each sample first (the annotations)
  template <class PubSubType>
  void add(const char* topic, cell_dds::Stream stream,
           std::function<void(const typename PubSubType::type&)> hook = nullptr) {
    const std::string dds_topic = cell_dds::namespaced(ns_, topic);
    const std::size_t index = channel<PubSubType>(dds_topic);
    starts_.push_back([this, dds_topic, stream, index, hook](LiveServer& server) -> std::shared_ptr<void> {
      using Data = typename PubSubType::type;
      return std::make_shared<cell_dds::Reader<PubSubType>>(p_, dds_topic, cell_dds::reader_qos(stream),
                                                            [&server, index, hook](Data&& m) {
                                                              if (hook) hook(m);
                                                              forward<PubSubType>(server, index, m);
                                                            });
    });
  }
  // a channel of type PubSubType on `dds_topic`; its index
  template <class PubSubType>
  std::size_t channel(const std::string& dds_topic) {
    const std::string ros_type = cell_dds::ros_type_name(PubSubType().getName());
    channels.push_back({cell_record::ros_topic_name(dds_topic), ros_type, cell_record::ros2msg_schema(ros_type)});
    return channels.size() - 1;
  }

  std::vector<std::shared_ptr<void>> start(LiveServer& server) {
    std::vector<std::shared_ptr<void>> readers;
    for (const auto& s : starts_) readers.push_back(s(server));
    return readers;
  }

  std::vector<Channel> channels;

 private:
  eprosima::fastdds::dds::DomainParticipant& p_;
  std::string ns_;
  std::vector<std::function<std::shared_ptr<void>(LiveServer&)>> starts_;
};

}  // namespace

Bridge::Bridge(eprosima::fastdds::dds::DomainParticipant& participant, const std::string& ns, ServerOptions options) {
  using cell_dds::Stream;
  Topics t(participant, ns);
  t.add<sensor_msgs::msg::dds_::Image_PubSubType>(cell_dds::kImageTopic, Stream::kFrame);
  t.add<sensor_msgs::msg::dds_::CameraInfo_PubSubType>(cell_dds::kCameraInfoTopic, Stream::kLatched);
  t.add<tf2_msgs::msg::dds_::TFMessage_PubSubType>(cell_dds::kTfTopic, Stream::kFrame);
  t.add<sensor_msgs::msg::dds_::JointState_PubSubType>(cell_dds::kJointStatesTopic, Stream::kFrame);
  t.add<std_msgs::msg::dds_::String_PubSubType>(cell_dds::kRobotDescriptionTopic, Stream::kLatched);
  t.add<cell_msgs::msg::dds_::ServoStatus_PubSubType>(cell_dds::kStatusTopic, Stream::kLatched);
  t.add<geometry_msgs::msg::dds_::TwistStamped_PubSubType>(cell_dds::kTwistTopic, Stream::kFrame);
  t.add<cell_msgs::msg::dds_::DecodedSpots_PubSubType>(cell_dds::kSpotsTopic, Stream::kFrame,
                                                       [this](const auto& m) { annotations_->on_spots(m); });
  t.add<cell_msgs::msg::dds_::SimStatus_PubSubType>(cell_dds::kSimStatusTopic, Stream::kFrame,
                                                    [this](const auto& m) { annotations_->on_status(m); });
  t.add<geometry_msgs::msg::dds_::PoseStamped_PubSubType>(cell_dds::kCameraPoseTopic, Stream::kFrame);
  t.add<cell_msgs::msg::dds_::SpotTruthArray_PubSubType>(cell_dds::kSpotTruthTopic, Stream::kFrame);
  t.add<rosgraph_msgs::msg::dds_::Clock_PubSubType>(cell_dds::kClockTopic, Stream::kClock);
  // what the simulator obeyed, not rt/sim/control: a viewer must not be a second reader of the
  // commands (a client publishing once on its first match would reach the viewer, not the cell)
  t.add<cell_msgs::msg::dds_::SimControl_PubSubType>(cell_dds::kAcceptedTopic, Stream::kCommand);
  const std::size_t drawn =
      t.channel<foxglove_msgs::msg::dds_::ImageAnnotations_PubSubType>(cell_dds::namespaced(ns, kAnnotationsTopic));
  channels_ = t.channels.size();
  server_ = std::make_unique<LiveServer>(options, "cellsim bridge", t.channels);
  LiveServer& server = *server_;
  annotations_ = std::make_unique<Annotations>(
      [&server, drawn](const Annotations::Drawn& a) {
        forward<foxglove_msgs::msg::dds_::ImageAnnotations_PubSubType>(server, drawn, a);
      },
      [&server, drawn] { return server.subscribed(drawn); });
  readers_ = t.start(*server_);
}

Bridge::~Bridge() {
  readers_.clear();  // no sample reaches the annotations or the server once they are gone
  annotations_.reset();
  server_.reset();
}

}  // namespace foxglove
