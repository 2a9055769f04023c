// The way from the servo's twist to the robot's motion when the loop has delays (issue 13),
// in simulated time: the twist computed from frame k reaches the robot `processing_frames`
// frames later, and the robot starts to follow it `actuation_s` after it arrives, following the
// previous one until then (fractions of a frame are integrated exactly, in pieces). The
// in-process runner and the cell's lockstep both drive the robot through it, so their traces
// stay equal with delays too.
#pragma once

#include <deque>
#include <utility>

#include "sim/robot/robot.hpp"

namespace sim {

class TwistDelay {
 public:
  TwistDelay(int processing_frames = 0, double actuation_s = 0);
  bool active() const { return processing_frames_ > 0 || actuation_s_ > 0; }
  // Moves the robot for the frame [t_s, t_s + dt_s) given this frame's twist: the limits of
  // every piece OR'ed, the applied twist averaged, the first event.
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

}  // namespace sim
