// Where the camera takes each frame's white reference frame (the projector casting white,
// docs/decoding.md, Appearance). A real camera takes it apart from the pattern frame, so while
// the camera moves the two are not taken at one pose: `lead` of a frame period before the
// pattern frame, on the screw motion from the frame before's pose (the camera moves from frame
// to frame by the twists answering them). Plain data; the in-process loop and `cellsim serve`
// both ask it, so the two render the same white frames.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <utility>

#include "sim/session/cell_state_machine.hpp"

namespace sim {

class WhiteFramePose {
 public:
  // lead: the share of a frame period (0..1) the white frame is taken before its pattern frame
  explicit WhiteFramePose(double lead) : lead_(lead) {}

  // The pose of frame f's white frame. Frames come in order; a repeated frame (lockstep sends an
  // unanswered frame again) gets the pose its first sending got.
  Eigen::Isometry3d at(const FrameOrder& f);
  // A command the cell obeyed may have moved the camera otherwise than by a twist (RESET, TEACH,
  // LOAD_SCENARIO): the next frame is not reached from the one before.
  void forget() { moving_from_.reset(); }

 private:
  double lead_;
  std::optional<Eigen::Isometry3d> moving_from_;  // the frame before's scene pose, while moving
  std::optional<std::pair<std::uint64_t, Eigen::Isometry3d>> last_;  // the last frame and its white pose
};

}  // namespace sim
