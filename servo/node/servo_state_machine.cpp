#include "servo/node/servo_state_machine.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "common/strict_yaml.hpp"

namespace servo {
namespace {

std::string size_text(std::uint64_t w, std::uint64_t h) { return std::to_string(w) + " x " + std::to_string(h); }

}  // namespace

ServoStateMachine::ServoStateMachine(std::unique_ptr<ServoPipeline> pipeline, ServoTiming timing)
    : pipeline_(std::move(pipeline)), timing_(timing), divergence_(pipeline_ ? pipeline_->config().divergence_ratio : 0),
      safe_stop_(pipeline_ ? pipeline_->config().safe_stop_frames : 0) {
  if (!pipeline_) throw std::invalid_argument("ServoStateMachine: no pipeline");
  if (!(timing_.lost_s > 0)) throw std::invalid_argument("ServoStateMachine: lost_s must be positive");
  state_ = pipeline_->taught() && timing_.autostart ? ServoState::kServoing : ServoState::kIdle;
}

void ServoStateMachine::on_command(int command) {
  // a START in force (servoing, or waiting for the teach frame to take effect)
  const bool was_running = started_;
  jump_pending_ = false;
  switch (command) {
    case static_cast<int>(cell_dds::SimCommand::kTeach): state_ = ServoState::kTeaching; break;
    case static_cast<int>(cell_dds::SimCommand::kStart):
      // commands can arrive before the teach frame: START then takes effect once taught
      started_ = true;
      divergence_.reset();
      safe_stop_.reset();
      if (pipeline_->taught() && state_ != ServoState::kTeaching) state_ = ServoState::kServoing;
      break;
    case static_cast<int>(cell_dds::SimCommand::kStep):
      if (pipeline_->taught() && state_ != ServoState::kTeaching) state_ = ServoState::kServoing;
      break;
    case static_cast<int>(cell_dds::SimCommand::kPause):
      started_ = false;
      state_ = ServoState::kStopped;
      break;
    case static_cast<int>(cell_dds::SimCommand::kReset):
    case static_cast<int>(cell_dds::SimCommand::kLoadScenario):
      // the robot jumps: what was servoing must be started again, unless the simulator
      // refused the command and runs on (see jump_pending_)
      started_ = false;
      if (state_ != ServoState::kTeaching) state_ = ServoState::kIdle;
      jump_pending_ = was_running;
      running_frames_since_jump_ = 0;
      last_running_stamp_.reset();
      break;
    default: break;  // the simulator refuses it; nothing changes here
  }
}

std::string ServoStateMachine::camera_info_problem(const CameraInfoMsg& c) {
  if (c.width == 0 || c.height == 0) return "rejected camera_info: size " + size_text(c.width, c.height);
  if (c.width > kMaxImageSide || c.height > kMaxImageSide ||
      static_cast<std::uint64_t>(c.width) * c.height > kMaxImagePixels)
    return "rejected camera_info: " + size_text(c.width, c.height) + " is beyond the limit of " +
           std::to_string(kMaxImageSide) + " per side and " + std::to_string(kMaxImagePixels) + " pixels";
  if (c.k.size() != 9) return "rejected camera_info: k has " + std::to_string(c.k.size()) + " values, expected 9";
  for (double v : c.k)
    if (!std::isfinite(v)) return "rejected camera_info: k is not finite";
  const double fx = c.k[0], fy = c.k[4], cx = c.k[2], cy = c.k[5];
  if (!(fx >= 1 && fx <= 1e5 && fy >= 1 && fy <= 1e5)) return "rejected camera_info: focal length outside [1, 1e5] px";
  if (!(cx >= -double(c.width) && cx <= 2.0 * c.width && cy >= -double(c.height) && cy <= 2.0 * c.height))
    return "rejected camera_info: principal point far outside the image";
  if (c.d.size() > kMaxDistortionCoefficients)
    return "rejected camera_info: " + std::to_string(c.d.size()) + " distortion coefficients (at most " +
           std::to_string(kMaxDistortionCoefficients) + ")";
  for (double v : c.d)
    if (!std::isfinite(v) || std::abs(v) > 10) return "rejected camera_info: distortion coefficient outside [-10, 10]";
  return "";
}

std::string ServoStateMachine::on_camera_info(const CameraInfoMsg& info) {
  std::string why = camera_info_problem(info);
  if (why.empty()) info_ = info;
  return why;
}

void ServoStateMachine::on_sim_status(const SimFrameStatus& s) {
  sim_status_seen_ = true;
  sim_statuses_.push_back(s);
  while (sim_statuses_.size() > kKeptFrameInfo) sim_statuses_.pop_front();
}

void ServoStateMachine::on_pose(const Stamp& stamp, const Eigen::Isometry3d& world_T_camera) {
  if (!world_T_camera.matrix().allFinite()) return;
  poses_seen_ = true;
  poses_.emplace_back(stamp, world_T_camera);
  while (poses_.size() > kKeptFrameInfo) poses_.pop_front();
}

const SimFrameStatus* ServoStateMachine::sim_status_for(const Stamp& s) const {
  for (auto it = sim_statuses_.rbegin(); it != sim_statuses_.rend(); ++it)
    if (it->stamp == s) return &*it;
  return nullptr;
}

std::optional<Eigen::Isometry3d> ServoStateMachine::pose_for(const Stamp& s) const {
  for (auto it = poses_.rbegin(); it != poses_.rend(); ++it)
    if (it->first == s) return it->second;
  return std::nullopt;
}

bool ServoStateMachine::frame_info_complete(const Stamp& s) const {
  return (!sim_status_seen_ || sim_status_for(s)) && (!poses_seen_ || pose_for(s));
}

std::string ServoStateMachine::reject_reason(const ImageView& img, const std::optional<CameraInfoMsg>& info) {
  // every size in 64 bits: width * 3 of a 32-bit width wraps (issue 9, item 1)
  if (img.encoding != "rgb8")
    return "rejected image: encoding '" + common::printable(img.encoding, 32) + "', expected rgb8";
  if (img.width == 0 || img.height == 0) return "rejected image: empty (" + size_text(img.width, img.height) + ")";
  if (img.width > kMaxImageSide || img.height > kMaxImageSide ||
      static_cast<std::uint64_t>(img.width) * img.height > kMaxImagePixels)
    return "rejected image: " + size_text(img.width, img.height) + " is beyond the limit of " +
           std::to_string(kMaxImageSide) + " per side";
  if (static_cast<std::uint64_t>(img.step) != static_cast<std::uint64_t>(img.width) * 3)
    return "rejected image: step " + std::to_string(img.step) + " for width " + std::to_string(img.width) + " (rgb8: " +
           std::to_string(static_cast<std::uint64_t>(img.width) * 3) + ")";
  if (static_cast<std::uint64_t>(img.size) != static_cast<std::uint64_t>(img.step) * img.height || img.data == nullptr)
    return "rejected image: " + std::to_string(img.size) + " bytes for " + size_text(img.width, img.height);
  if (!info) return "waiting for camera_info";
  if (info->width != img.width || info->height != img.height)
    return "rejected image: " + size_text(img.width, img.height) + ", camera_info says " +
           size_text(info->width, info->height);
  return "";
}

ServoReply ServoStateMachine::reply(const Stamp& stamp, std::string reason) const {
  ServoReply r;
  r.stamp = stamp;
  r.state = state();
  r.reason = std::move(reason);
  r.iteration = iteration_;
  r.error_norm = error_norm_;
  r.decoded = decoded_;
  r.matched = matched_;
  return r;
}

// what it servoes on, said from the start: a client learns it from the latched status
ServoReply ServoStateMachine::ready() {
  return reply(Stamp{}, "ready (visual features: " + control::to_string(pipeline_->config().law.features) + ")");
}

ServoReply ServoStateMachine::shutdown() {
  state_ = ServoState::kStopped;
  lost_ = false;
  return reply(last_stamp_, "servo shut down");
}

std::optional<ServoReply> ServoStateMachine::tick(double now_s) {
  const bool active = state_ == ServoState::kServoing || state_ == ServoState::kConverged || state_ == ServoState::kTeaching;
  if (!last_image_s_ || lost_ || !active || now_s - *last_image_s_ <= timing_.lost_s) return std::nullopt;
  // LOST is a condition on top of the state, not a state that replaces it: when the images
  // come back the servo goes on as it was (a START that came meanwhile stays in force)
  lost_ = true;
  return reply(last_stamp_, "no image for " + std::to_string(static_cast<int>(timing_.lost_s * 1e3)) + " ms");
}

std::string ServoStateMachine::white_problem(const ImageView& img, const ImageView* white) const {
  if (!white)
    return pipeline_->config().white_frame ? "rejected image: no white reference frame with its stamp (--white-frame)"
                                           : std::string();
  if (!(white->stamp == img.stamp)) {
    const auto text = [](const Stamp& t) {
      char b[32];
      std::snprintf(b, sizeof b, "%d.%09u s", t.sec, t.nanosec);
      return std::string(b);
    };
    return "white frame: rejected image: stamped " + text(white->stamp) + ", the image " + text(img.stamp);
  }
  const std::string bad = reject_reason(*white, info_);
  return bad.empty() ? bad : "white frame: " + bad;
}

ServoReply ServoStateMachine::on_image(const ImageView& img, double now_s, const ImageView* white) {
  last_image_s_ = now_s;
  lost_ = false;
  ++images_;
  last_stamp_ = img.stamp;
  std::string bad = reject_reason(img, info_);
  if (bad.empty()) bad = white_problem(img, white);
  if (!bad.empty()) {
    ++rejected_;
    return reply(img.stamp, bad);
  }
  calibration::CameraIntrinsics& cam = pipeline_->config().camera;
  cam.fx = info_->k[0];
  cam.cx = info_->k[2];
  cam.fy = info_->k[4];
  cam.cy = info_->k[5];
  for (std::size_t i = 0; i < cam.distortion.size(); ++i) cam.distortion[i] = i < info_->d.size() ? info_->d[i] : 0.0;

  const auto as_mat = [](const ImageView& v) {
    return cv::Mat(static_cast<int>(v.height), static_cast<int>(v.width), CV_8UC3, const_cast<std::uint8_t*>(v.data),
                   v.step);
  };
  const cv::Mat rgb = as_mat(img);
  const cv::Mat reference = white ? as_mat(*white) : cv::Mat();
  int detected = 0;
  std::vector<ImageSpot> spots;
  const std::optional<Eigen::Isometry3d> pose = pose_for(img.stamp);
  try {
    spots = pipeline_->locate(rgb, pose, &detected, white ? &reference : nullptr, &decode_scratch_);
  } catch (const std::exception& e) {
    ++rejected_;
    return reply(img.stamp, "rejected image: " + common::printable(e.what(), 200));
  }
  return answer(img.stamp, spots, detected, pose);
}

ServoReply ServoStateMachine::on_spots(const Stamp& stamp, const std::vector<ImageSpot>& spots, int detected,
                                       double now_s) {
  last_image_s_ = now_s;
  lost_ = false;
  ++images_;
  last_stamp_ = stamp;
  return answer(stamp, spots, detected, pose_for(stamp));
}

ServoReply ServoStateMachine::answer(const Stamp& stamp, const std::vector<ImageSpot>& spots, int detected,
                                     const std::optional<Eigen::Isometry3d>& pose) {
  decoded_ = static_cast<std::uint32_t>(spots.size());
  const SimFrameStatus* sim = sim_status_for(stamp);
  if (sim_status_seen_ && !sim) {
    ServoReply r = reply(stamp, "no simulator status for this frame: not answered");
    r.answer = false;
    return r;
  }
  const auto with_spots = [&](ServoReply r) {
    r.spots = spots;
    r.detected = detected;
    return r;
  };
  // teach from the simulator's teach frame (camera at the desired pose); a simulator that
  // sends no status: from the first image after TEACH
  const bool teach_frame = sim ? sim->teach : (!sim_status_seen_ && state_ == ServoState::kTeaching);
  if (teach_frame) return with_spots(teach(stamp, spots, pose));
  std::string notice = sim ? follow_refused_jump(*sim, stamp) : std::string();
  const std::optional<ServoReply> wait = waiting(stamp, sim);
  ServoReply r = with_spots(wait ? *wait : servo_step(stamp, spots, pose));
  r.notice = std::move(notice);
  return r;
}

ServoReply ServoStateMachine::teach(const Stamp& stamp, const std::vector<ImageSpot>& spots,
                                    const std::optional<Eigen::Isometry3d>& pose) {
  const int n = pipeline_->teach(spots, pose);
  matched_ = static_cast<std::uint32_t>(n);
  iteration_ = 0;
  divergence_.reset();
  safe_stop_.reset();
  if (!pipeline_->taught()) {
    state_ = ServoState::kTeaching;
    return reply(stamp, "teach frame has no decodable spots: send TEACH again");
  }
  state_ = timing_.autostart || started_ ? ServoState::kServoing : ServoState::kIdle;
  ServoReply r = reply(stamp, "taught " + std::to_string(n) + " features");
  r.taught = true;
  return r;
}

std::string ServoStateMachine::follow_refused_jump(const SimFrameStatus& sim, const Stamp& stamp) {
  // The simulator is the authority on whether the run goes: a frame it runs (START in force,
  // the twist applied) while this servo, taught, sits idle means a START the simulator heard
  // and this servo did not (a servo started after the command, or one missing it on
  // rt/sim/accepted, which is not kept for late joiners). The servo follows it, once the frame cannot be one from
  // before a RESET it heard (jump_pending_, below); a servo that stopped itself or was paused
  // stays stopped (its state is kStopped, not kIdle).
  if (!jump_pending_ && !started_ && state_ == ServoState::kIdle && sim.running && sim.applies_twist &&
      pipeline_->taught()) {
    started_ = true;
    divergence_.reset();
    safe_stop_.reset();
    state_ = ServoState::kServoing;
    return "the simulator runs (a START this servo did not hear): servoing";
  }
  if (!jump_pending_) return {};
  if (!sim.running || !sim.applies_twist) {
    jump_pending_ = false;  // the simulator obeyed: START is needed again
  } else if (!last_running_stamp_ || !(*last_running_stamp_ == stamp)) {
    last_running_stamp_ = stamp;
    if (++running_frames_since_jump_ >= kRefusalFrames && pipeline_->taught()) {
      jump_pending_ = false;
      started_ = true;
      state_ = ServoState::kServoing;
      return "the simulator runs on after RESET/LOAD_SCENARIO (it refused the command): servoing on";
    }
  }
  return {};
}

std::optional<ServoReply> ServoStateMachine::waiting(const Stamp& stamp, const SimFrameStatus* sim) const {
  if (state_ == ServoState::kTeaching) return reply(stamp, "waiting for the teach frame");
  if (state_ != ServoState::kServoing && state_ != ServoState::kConverged)
    return reply(stamp, pipeline_->taught() ? "waiting for START" : "no reference: send TEACH");
  // a frame whose twist the simulator will not apply (paused, or rendered before START took
  // effect) can neither move the robot nor prove convergence (issue 9, item 8)
  if (sim && !sim->applies_twist) return reply(stamp, "waiting: the simulator is not applying twists");
  return std::nullopt;
}

ServoReply ServoStateMachine::servo_step(const Stamp& stamp, const std::vector<ImageSpot>& spots,
                                         const std::optional<Eigen::Isometry3d>& pose) {
  StepResult step;
  try {
    step = pipeline_->step(spots, pose);
  } catch (const std::exception& e) {
    return reply(stamp, common::printable(e.what(), 200));
  }
  ++iteration_;
  error_norm_ = step.control.error_norm;
  matched_ = static_cast<std::uint32_t>(step.matched.size());
  // a loop running away is stopped rather than followed; so is a safe stop that lasts (START resumes)
  const std::string why = step.control.status == control::ControlStatus::kServoing
                              ? divergence_.check(step.control.error_norm) : std::string();
  std::string reason;
  if (why.empty()) {
    state_ = step.control.status == control::ControlStatus::kConverged ? ServoState::kConverged : ServoState::kServoing;
    if (step.control.status == control::ControlStatus::kConverged) reason = step.control.reason;
    else if (step.control.status != control::ControlStatus::kServoing) reason = "safe stop: " + step.control.reason;
  }
  const bool lasting = why.empty() && safe_stop_.lasting(step.control.status);
  if (!why.empty() || lasting) {
    state_ = ServoState::kStopped;
    started_ = false;
    ServoReply r = reply(stamp, lasting ? reason + " (" + std::to_string(safe_stop_.frames()) + " frames): stopped"
                                        : why + ": stopped");
    r.step = std::move(step);
    return r;
  }
  ServoReply r = reply(stamp, reason);
  r.twist = step.control.twist;
  if (!r.twist.allFinite()) {
    r.twist.setZero();
    r.reason = "control law gave a non-finite twist: zero sent";
  }
  r.step = std::move(step);
  return r;
}

}  // namespace servo
