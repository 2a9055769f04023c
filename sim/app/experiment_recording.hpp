// `cellsim experiment --record FILE.mcap`: the in-process loop recorded as the two-process
// run would be (cellsim serve --record), topic for topic and in the services' order, so that
// Foxglove, ros2 bag and `servo replay` read both alike. Log and publish times are the loop's
// simulated time: an in-process run has no other clock.
#pragma once

#include <memory>

#include "foxglove/annotations.hpp"
#include "record/recorder.hpp"
#include "sim/loop/in_memory_loop.hpp"

namespace cellsim {

class ExperimentRecording : public loop::LoopTap {
 public:
  ExperimentRecording(const sim::Cell& cell, cell_record::RecordOptions options, const mcap::KeyValues& metadata);
  void on_start(const servo::CameraInfoMsg& info, const sim::CellStateMachine& cell) override;
  void on_command(const sim::CommandMsg& c, double now_s) override;
  void on_accepted(const sim::CommandMsg& c, double now_s) override;
  void on_frame(const sim::FrameOrder& f, const sim::CellStateMachine& cell, const cv::Mat* white, const cv::Mat* rgb,
                double now_s) override;
  void on_reply(const servo::ServoReply& r, double now_s) override;
  // closes the file; "PATH (N MB, M messages on T topics)" and the count per topic
  std::string close();

 private:
  template <typename PubSubType>
  void put(const char* topic, cell_dds::Stream stream, const typename PubSubType::type& m, double now_s);

  const sim::Cell& cell_;
  cell_record::Recorder recorder_;
  // /servo/annotations, drawn from the statuses and decoded spots as cellsim serve --record
  // draws them: the recording shows the decoded ids and desired points in Foxglove
  foxglove::Annotations annotations_;
  double drawing_s_ = 0;  // the time of the spots being drawn
  bool images_;           // images recorded (and so their annotations)
  double last_s_ = 0;
  std::uint64_t tick_ = 0;  // keeps log times apart within one instant, in publication order
};

}  // namespace cellsim
