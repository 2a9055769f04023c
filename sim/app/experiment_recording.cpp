#include "sim/app/experiment_recording.hpp"

#include <algorithm>
#include <cmath>

#include "cell_msgsPubSubTypes.h"
#include "foxglove_msgsPubSubTypes.h"
#include "geometry_msgsPubSubTypes.h"
#include "rosgraph_msgsPubSubTypes.h"
#include "sensor_msgsPubSubTypes.h"
#include "servo/messages/servo_messages.hpp"
#include "sim/messages/cell_messages.hpp"
#include "std_msgsPubSubTypes.h"
#include "tf2_msgsPubSubTypes.h"

namespace cellsim {

using cell_dds::Stream;

ExperimentRecording::ExperimentRecording(const sim::Cell& cell, cell_record::RecordOptions options,
                                         const mcap::KeyValues& metadata)
    : cell_(cell),
      recorder_(options, metadata),
      annotations_([this](const foxglove::Annotations::Drawn& a) {
        put<foxglove_msgs::msg::dds_::ImageAnnotations_PubSubType>(foxglove::kAnnotationsTopic, Stream::kFrame, a,
                                                                   drawing_s_);
      }),
      images_(options.images) {}

template <typename PubSubType>
void ExperimentRecording::put(const char* topic, Stream stream, const typename PubSubType::type& m, double now_s) {
  // one nanosecond apart within an instant, so that the log times keep the publication order
  if (now_s != last_s_) tick_ = 0;
  last_s_ = now_s;
  const auto ns = static_cast<std::uint64_t>(std::llround(now_s * 1e9)) + tick_++;
  recorder_.record<PubSubType>(topic, stream, m, ns, ns);
}

void ExperimentRecording::on_start(const servo::CameraInfoMsg& info, const sim::CellStateMachine& cell) {
  auto ci = sim::wire::camera_info(cell.scenario(), cell_dds::stamp_of(0, cell.dt()));
  // what the loop gave the servo (its calibrated camera), as the service's camera_info says it
  ci.width(info.width);
  ci.height(info.height);
  if (info.k.size() == 9) std::copy(info.k.begin(), info.k.end(), ci.k().begin());
  ci.d(info.d);
  put<sensor_msgs::msg::dds_::CameraInfo_PubSubType>(cell_dds::kCameraInfoTopic, Stream::kLatched, ci, 0);
  put<std_msgs::msg::dds_::String_PubSubType>(cell_dds::kRobotDescriptionTopic, Stream::kLatched,
                                               sim::wire::description(cell.scenario()), 0);
}

void ExperimentRecording::on_command(const sim::CommandMsg& c, double now_s) {
  put<cell_msgs::msg::dds_::SimControl_PubSubType>(cell_dds::kControlTopic, Stream::kCommand, sim::wire::control(c), now_s);
}

void ExperimentRecording::on_accepted(const sim::CommandMsg& c, double now_s) {
  put<cell_msgs::msg::dds_::SimControl_PubSubType>(cell_dds::kAcceptedTopic, Stream::kCommand, sim::wire::control(c), now_s);
}

void ExperimentRecording::on_frame(const sim::FrameOrder& f, const sim::CellStateMachine& cell, const cv::Mat* white,
                                   const cv::Mat* rgb, double now_s) {
  const auto stamp = cell_dds::stamp_of(f.index, cell.dt());
  const sim::Scenario& s = cell.scenario();
  const auto status = sim::wire::frame_status(f, cell, stamp, {});
  put<cell_msgs::msg::dds_::SimStatus_PubSubType>(cell_dds::kSimStatusTopic, Stream::kFrame, status, now_s);
  annotations_.on_status(status);
  put<geometry_msgs::msg::dds_::PoseStamped_PubSubType>(cell_dds::kCameraPoseTopic, Stream::kFrame,
                                                        sim::wire::camera_pose(f, stamp), now_s);
  put<tf2_msgs::msg::dds_::TFMessage_PubSubType>(cell_dds::kTfTopic, Stream::kFrame, sim::wire::transforms(s, f, stamp), now_s);
  if (sim::wire::has_joints(s, f))
    put<sensor_msgs::msg::dds_::JointState_PubSubType>(cell_dds::kJointStatesTopic, Stream::kFrame,
                                                       sim::wire::joint_state(f, stamp), now_s);
  if (white)
    put<sensor_msgs::msg::dds_::Image_PubSubType>(cell_dds::kWhiteImageTopic, Stream::kFrame,
                                                  sim::wire::image(*white, stamp), now_s);
  if (rgb)
    put<sensor_msgs::msg::dds_::Image_PubSubType>(cell_dds::kImageTopic, Stream::kFrame, sim::wire::image(*rgb, stamp), now_s);
  else  // the ideal source: the truth is what the servo stepped on
    put<cell_msgs::msg::dds_::SpotTruthArray_PubSubType>(cell_dds::kSpotTruthTopic, Stream::kFrame,
                                                         sim::wire::spot_truth(cell_, f, stamp), now_s);
  put<rosgraph_msgs::msg::dds_::Clock_PubSubType>(cell_dds::kClockTopic, Stream::kClock, sim::wire::clock(stamp), now_s);
}

void ExperimentRecording::on_reply(const servo::ServoReply& r, double now_s) {
  if (r.spots) {
    const auto spots = servo::spots_message(r);
    put<cell_msgs::msg::dds_::DecodedSpots_PubSubType>(cell_dds::kSpotsTopic, Stream::kFrame, spots, now_s);
    drawing_s_ = now_s;
    if (images_) annotations_.on_spots(spots);
  }
  put<cell_msgs::msg::dds_::ServoStatus_PubSubType>(cell_dds::kStatusTopic, Stream::kLatched, servo::status_message(r),
                                                    now_s);
  put<geometry_msgs::msg::dds_::TwistStamped_PubSubType>(cell_dds::kTwistTopic, Stream::kFrame, servo::twist_message(r),
                                                         now_s);
}

std::string ExperimentRecording::close() {
  const mcap::WriteSummary w = recorder_.close();
  return recorder_.describe(w) + "\n  recorded messages: " + cell_record::Recorder::topic_counts(w);
}

}  // namespace cellsim
