#include "sim/robot/twist_delay.hpp"

#include <algorithm>

namespace sim {

TwistDelay::TwistDelay(int processing_frames, double actuation_s)
    : processing_frames_(std::max(0, processing_frames)), actuation_s_(std::max(0.0, actuation_s)) {
  reset();
}

void TwistDelay::reset() {
  in_flight_.assign(static_cast<std::size_t>(processing_frames_), Vector6d::Zero());
  pending_.clear();
  followed_.setZero();
}

MotionReport TwistDelay::step(Robot& robot, const Vector6d& twist, double t_s, double dt_s, const Workspace& workspace) {
  in_flight_.push_back(twist);
  pending_.emplace_back(t_s + actuation_s_, in_flight_.front());
  in_flight_.pop_front();
  MotionReport total;
  double t = t_s;
  const double end = t_s + dt_s;
  while (t < end) {
    while (!pending_.empty() && pending_.front().first <= t + 1e-12) {
      followed_ = pending_.front().second;
      pending_.pop_front();
    }
    const double until = pending_.empty() ? end : std::min(end, pending_.front().first);
    if (until > t) {
      // a whole frame in one piece moves exactly as an undelayed step does
      const double piece = (t == t_s && until == end) ? dt_s : until - t;
      const MotionReport r = robot.move(followed_, piece, workspace);
      total.limits |= r.limits;
      total.applied += r.applied * (piece / dt_s);
      if (total.event.empty()) total.event = r.event;
    }
    t = std::max(until, t + 1e-12);
  }
  return total;
}

}  // namespace sim
