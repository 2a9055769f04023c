// The servo service's logic, as `servo run` runs it: commands (TEACH, START, PAUSE, RESET),
// the checks every image and camera_info pass, teaching from the simulator's teach frame,
// servoing only on frames whose twist the simulator applies, and LOST when the images stop.
// A pure state machine over plain messages and a time argument: the app subscribes, converts,
// calls it and publishes the ServoReply it returns. It never waits and never sees DDS.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "protocol/servo_state.hpp"
#include "protocol/sim_command.hpp"
#include "servo/pipeline/servo_pipeline.hpp"

namespace servo {

// cell_msgs/ServoStatus states (protocol/servo_state.hpp, checked against the IDL)
using cell_dds::ServoState;

// Limits on what an image or camera_info may claim (docs/topics.md, Safety).
inline constexpr std::uint32_t kMaxImageSide = 4096;
inline constexpr std::uint64_t kMaxImagePixels = 4096ull * 2304;
inline constexpr std::size_t kMaxDistortionCoefficients = 14;

struct Stamp {
  std::int32_t sec = 0;
  std::uint32_t nanosec = 0;
  bool operator==(const Stamp& o) const { return sec == o.sec && nanosec == o.nanosec; }
};

// sensor_msgs/Image as received (untrusted): a view, nothing is copied.
struct ImageView {
  Stamp stamp;
  std::string_view encoding;
  std::uint32_t width = 0, height = 0, step = 0;
  std::uint8_t is_bigendian = 0;
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
};

// sensor_msgs/CameraInfo as received (untrusted).
struct CameraInfoMsg {
  std::uint32_t width = 0, height = 0;
  std::vector<double> k;  // 3 x 3, row major
  std::vector<double> d;  // plumb bob k1 k2 p1 p2 k3 (more are refused beyond kMaxDistortionCoefficients)
};

// cell_msgs/SimStatus: the simulator's word on a frame.
struct SimFrameStatus {
  Stamp stamp;
  bool applies_twist = false;
  bool teach = false;
  bool running = false;  // the simulator's state is RUNNING (START in force)
};

// What to publish: a twist (always, zero unless servoing), the status, the decoded spots.
struct ServoReply {
  Stamp stamp;
  control::Vector6d twist = control::Vector6d::Zero();
  ServoState state = ServoState::kIdle;
  std::string reason;
  std::uint32_t iteration = 0;
  double error_norm = 0;
  std::uint32_t decoded = 0, matched = 0;
  std::optional<std::vector<ImageSpot>> spots;  // when the image was decoded
  int detected = 0;
  bool taught = false;                          // this image taught s*
  // the control law's iteration in full, when one was made (in-process tools read it; the
  // service publishes what the fields above say)
  std::optional<StepResult> step;
  // false: publish nothing for this image. Its simulator status never came, so what the frame
  // is (teach frame? applied?) is unknown; in lockstep the simulator sends it again.
  bool answer = true;
  // a line for the service's log, when something happened worth saying (the state machine
  // prints nothing itself)
  std::string notice;
};

struct ServoTiming {
  double lost_s = 0.5;   // no image for this long while servoing: zero twist, state LOST
  bool autostart = false;  // servo as soon as taught (no START needed)
};

class ServoStateMachine {
 public:
  ServoStateMachine(std::unique_ptr<ServoPipeline> pipeline, ServoTiming timing);

  void on_command(int command);
  // Returns the reason the camera_info was refused (the previous one stays in force), or "".
  std::string on_camera_info(const CameraInfoMsg& info);
  void on_sim_status(const SimFrameStatus& s);
  void on_pose(const Stamp& stamp, const Eigen::Isometry3d& world_T_camera);

  // True when the simulator's status (and pose, if it sends poses) for this stamp is here:
  // the app may wait a little for them before calling on_image.
  bool frame_info_complete(const Stamp& stamp) const;

  // One image: checked, decoded, and answered. `white` (optional): the white reference frame
  // taken at the same pose (vision/reference.hpp), checked as the image is, held to its size and
  // its stamp; with ServoConfig::white_frame an image without one is rejected.
  ServoReply on_image(const ImageView& image, double now_s, const ImageView* white = nullptr);
  // Spots located by someone else (the simulator's truth for the `ideal` feature source, or
  // decoded spots some of whose ids an experiment swapped), answered as an image would be.
  ServoReply on_spots(const Stamp& stamp, const std::vector<ImageSpot>& spots, int detected, double now_s);
  // Time passes: LOST when the images stop while servoing (once per outage).
  std::optional<ServoReply> tick(double now_s);
  // The reply a clean shutdown publishes: zero twist, STOPPED.
  ServoReply shutdown();
  // The "ready" status.
  ServoReply ready();

  ServoState state() const { return lost_ ? ServoState::kLost : state_; }
  const ServoPipeline& pipeline() const { return *pipeline_; }
  long images() const { return images_; }
  long rejected() const { return rejected_; }

  // Checks before decoding; returns why the image is unusable, or "".
  static std::string reject_reason(const ImageView& image, const std::optional<CameraInfoMsg>& info);
  // Checks a camera_info; returns why it is unusable, or "".
  static std::string camera_info_problem(const CameraInfoMsg& info);

  static constexpr std::size_t kKeptFrameInfo = 16;

 private:
  ServoReply reply(const Stamp& stamp, std::string reason) const;
  // why the white frame beside `image` (none: null) makes it unusable, or ""
  std::string white_problem(const ImageView& image, const ImageView* white) const;
  // what follows the decoding: teaching, or one step of the control law
  ServoReply answer(const Stamp& stamp, const std::vector<ImageSpot>& spots, int detected,
                    const std::optional<Eigen::Isometry3d>& pose);
  // the stages of answer(): the teach frame; the simulator's word on whether the run goes (a
  // START only it heard, a RESET or LOAD_SCENARIO it refused: a notice when the servo follows
  // it); what a frame waits for; one law iteration
  ServoReply teach(const Stamp& stamp, const std::vector<ImageSpot>& spots, const std::optional<Eigen::Isometry3d>& pose);
  std::string follow_refused_jump(const SimFrameStatus& sim, const Stamp& stamp);
  std::optional<ServoReply> waiting(const Stamp& stamp, const SimFrameStatus* sim) const;
  ServoReply servo_step(const Stamp& stamp, const std::vector<ImageSpot>& spots,
                        const std::optional<Eigen::Isometry3d>& pose);
  const SimFrameStatus* sim_status_for(const Stamp& s) const;
  std::optional<Eigen::Isometry3d> pose_for(const Stamp& s) const;

  std::unique_ptr<ServoPipeline> pipeline_;
  ServoTiming timing_;
  ServoState state_ = ServoState::kIdle;
  bool lost_ = false;
  bool started_ = false;
  // A RESET or LOAD_SCENARIO idles the servo, but the simulator may refuse it (issue 18,
  // item 11: LOAD_SCENARIO "" right after START stopped the run 6-10 mm off). Frames that the
  // simulator renders running and applying twists after the command prove it refused: after
  // kRefusalFrames of them the servo goes on as it was. A frame that is not running proves
  // the command was obeyed.
  static constexpr int kRefusalFrames = 3;
  bool jump_pending_ = false;
  int running_frames_since_jump_ = 0;
  std::optional<Stamp> last_running_stamp_;
  std::optional<CameraInfoMsg> info_;
  std::deque<SimFrameStatus> sim_statuses_;
  std::deque<std::pair<Stamp, Eigen::Isometry3d>> poses_;
  bool sim_status_seen_ = false, poses_seen_ = false;
  std::optional<double> last_image_s_;
  Stamp last_stamp_;
  long images_ = 0, rejected_ = 0;
  std::uint32_t iteration_ = 0;
  control::DivergenceWatch divergence_;  // from the first step after START or teaching
  control::SafeStopWatch safe_stop_;      // the same
  double error_norm_ = 0;
  std::uint32_t decoded_ = 0, matched_ = 0;
  vision::DecodeScratch decode_scratch_;  // the decoder's room, from image to image
};

}  // namespace servo
