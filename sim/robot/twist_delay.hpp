// The way from the servo's twist to the robot's motion when the loop has delays (issue 13),
// in simulated time: the twist computed from frame k reaches the robot `processing_frames`
// frames later, and the robot starts to follow it `actuation_s` after it arrives, following the
// previous one until then (fractions of a frame are integrated exactly, in pieces). The
// in-process runner and the cell's lockstep both drive the robot through it, so their traces
// stay equal with delays too.
#pragma once

#include <cstddef>
#include <deque>
#include <utility>

#include "sim/robot/robot.hpp"

namespace sim {

class TwistDelay {
 public:
  TwistDelay(int processing_frames = 0, double actuation_s = 0);
  // Moves the robot for the frame [t_s, t_s + dt_s) given this frame's twist: the limits of
  // every piece OR'ed, the applied twist averaged, the first event. Without delays this is
  // exactly robot.move(twist, dt_s).
  MotionReport step(Robot& robot, const Vector6d& twist, double t_s, double dt_s, const Workspace& workspace);
  // forgets the twists on their way (a reset, a new run): the robot holds still until the
  // next ones arrive
  void reset();

 private:
  int processing_frames_;
  double actuation_s_;
  std::deque<Vector6d> in_flight_;                 // computed, not at the robot yet
  std::deque<std::pair<double, Vector6d>> pending_;  // at the robot, followed from .first on
  Vector6d followed_ = Vector6d::Zero();
};

// What a camera with an acquisition delay shows: push each frame's scene, get the one of
// `frames` frames ago (the oldest kept until there are that many).
template <class Scene>
class FrameDelay {
 public:
  explicit FrameDelay(int frames = 0) : keep_(static_cast<std::size_t>(frames > 0 ? frames : 0) + 1) {}
  const Scene& push(Scene now) {
    scenes_.push_back(std::move(now));
    while (scenes_.size() > keep_) scenes_.pop_front();
    return scenes_.front();
  }
  void clear() { scenes_.clear(); }

 private:
  std::size_t keep_;
  std::deque<Scene> scenes_;
};

}  // namespace sim
