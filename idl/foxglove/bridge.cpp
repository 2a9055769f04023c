#include "foxglove/bridge.hpp"

#include <functional>

#include <deque>
#include <map>
#include <mutex>

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
  // the sample's CDR bytes, as the wire carries them, to the channel's subscribers (none: the
  // sample is not serialised)
  template <class PubSubType>
  static void forward(LiveServer& server, std::size_t index, typename PubSubType::type& m) {
    if (!server.subscribed(index)) return;
    PubSubType type;
    eprosima::fastrtps::rtps::SerializedPayload_t payload(type.getSerializedSizeProvider(&m)());
    if (!type.serialize(&m, &payload)) return;
    server.publish(index, cell_record::wall_ns(), payload.data, payload.length);
  }

  eprosima::fastdds::dds::DomainParticipant& p_;
  std::string ns_;
  std::vector<std::function<std::shared_ptr<void>(LiveServer&)>> starts_;
};

namespace fx = foxglove_msgs::msg::dds_;

fx::Color_ colour(double r, double g, double b, double a = 1.0) {
  fx::Color_ c;
  c.r(r), c.g(g), c.b(b), c.a(a);
  return c;
}
fx::Point2_ point(double u, double v) {
  fx::Point2_ p;
  p.x(u + 0.5), p.y(v + 0.5);  // Foxglove's origin: the top-left pixel's corner; ours: its centre
  return p;
}

}  // namespace

// What the live view draws over the camera image (`/servo/annotations`, foxglove_msgs/
// ImageAnnotations): each decoded spot ringed and labelled with its id, the desired points (the
// spots decoded in the teach frame, which /sim/status names) as hollow rings, and each matched
// spot's error vector to its desired point. Built from /servo/spots and /sim/status alone, as
// any client could.
class Annotations {
 public:
  using Spots = cell_msgs::msg::dds_::DecodedSpots_;
  Annotations(LiveServer& server, std::size_t channel) : server_(server), channel_(channel) {}

  void on_status(const cell_msgs::msg::dds_::SimStatus_& s) {
    std::lock_guard<std::mutex> l(m_);
    if (s.state() != 3) return;  // SimStatus TEACHING: the teach frame
    teach_ = key(s.header().stamp());
    for (const Spots& x : recent_)
      if (key(x.header().stamp()) == teach_) learn(x);
  }
  void on_spots(const Spots& x) {
    std::lock_guard<std::mutex> l(m_);
    if (key(x.header().stamp()) == teach_) learn(x);
    recent_.push_back(x);
    if (recent_.size() > 16) recent_.pop_front();
    if (!server_.subscribed(channel_)) return;
    fx::ImageAnnotations_ a = draw(x);
    fx::ImageAnnotations_PubSubType type;
    eprosima::fastrtps::rtps::SerializedPayload_t payload(type.getSerializedSizeProvider(&a)());
    if (type.serialize(&a, &payload)) server_.publish(channel_, cell_record::wall_ns(), payload.data, payload.length);
  }

 private:
  static std::pair<std::int32_t, std::uint32_t> key(const builtin_interfaces::msg::dds_::Time_& t) {
    return {t.sec(), t.nanosec()};
  }
  void learn(const Spots& x) {
    desired_.clear();
    for (const auto& s : x.spots()) desired_[{s.row(), s.col()}] = {s.u(), s.v()};
  }
  fx::ImageAnnotations_ draw(const Spots& x) const {
    fx::ImageAnnotations_ a;
    for (const auto& [id, uv] : desired_) {
      fx::CircleAnnotation_ c;
      c.timestamp(x.header().stamp()), c.position(point(uv.first, uv.second)), c.diameter(12), c.thickness(1);
      c.outline_color(colour(1.0, 0.85, 0.1)), c.fill_color(colour(0, 0, 0, 0));
      a.circles().push_back(c);
    }
    fx::PointsAnnotation_ errors;
    errors.timestamp(x.header().stamp()), errors.type(4), errors.thickness(1.5);
    errors.outline_color(colour(1.0, 0.85, 0.1));
    for (const auto& s : x.spots()) {
      fx::CircleAnnotation_ c;
      c.timestamp(x.header().stamp()), c.position(point(s.u(), s.v())), c.diameter(10), c.thickness(1.5);
      c.outline_color(colour(1, 1, 1)), c.fill_color(colour(0, 0, 0, 0));
      a.circles().push_back(c);
      fx::TextAnnotation_ t;
      t.timestamp(x.header().stamp()), t.position(point(s.u() + 6, s.v() - 4));
      t.text(std::to_string(s.row()) + "," + std::to_string(s.col())), t.font_size(9);
      t.text_color(colour(1, 1, 1)), t.background_color(colour(0, 0, 0, 0.5));
      a.texts().push_back(t);
      if (const auto d = desired_.find({s.row(), s.col()}); d != desired_.end()) {
        errors.points().push_back(point(s.u(), s.v()));
        errors.points().push_back(point(d->second.first, d->second.second));
      }
    }
    if (!errors.points().empty()) a.points().push_back(errors);
    return a;
  }

  LiveServer& server_;
  std::size_t channel_;
  std::mutex m_;
  std::pair<std::int32_t, std::uint32_t> teach_{-1, 0};
  std::map<std::pair<int, int>, std::pair<double, double>> desired_;
  std::deque<Spots> recent_;
};

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
  t.add<cell_msgs::msg::dds_::SimControl_PubSubType>(cell_dds::kControlTopic, Stream::kCommand);
  const std::size_t drawn = t.channel<fx::ImageAnnotations_PubSubType>(cell_dds::namespaced(ns, "rt/servo/annotations"));
  channels_ = t.channels.size();
  server_ = std::make_unique<LiveServer>(options, "cellsim bridge", t.channels);
  annotations_ = std::make_unique<Annotations>(*server_, drawn);
  readers_ = t.start(*server_);
}

Bridge::~Bridge() {
  readers_.clear();  // no sample reaches the annotations or the server once they are gone
  annotations_.reset();
  server_.reset();
}

}  // namespace foxglove
