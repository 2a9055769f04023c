#include "sim/experiment/servo_env.hpp"

#include <cmath>
#include <stdexcept>

#include "protocol/sim_command.hpp"
#include "sim/experiment/campaign.hpp"

namespace experiment {
namespace {

std::string state_name(servo::ServoState s) {
  switch (s) {
    case servo::ServoState::kIdle: return "idle";
    case servo::ServoState::kTeaching: return "teaching";
    case servo::ServoState::kServoing: return "servoing";
    case servo::ServoState::kConverged: return "converged";
    case servo::ServoState::kLost: return "lost";
    case servo::ServoState::kStopped: return "stopped";
  }
  return "unknown";
}

sim::CommandMsg command(cell_dds::SimCommand c, std::optional<Eigen::Isometry3d> pose = std::nullopt) {
  return {static_cast<int>(c), "", 0, pose};
}

}  // namespace

ServoEnv::ServoEnv(const sim::Cell& cell, EnvOptions options) : cell_(cell), options_(std::move(options)) {
  if (options_.max_steps < 1 || options_.max_steps > 1000000)
    throw std::invalid_argument("max_steps must be in [1, 1000000], got " + std::to_string(options_.max_steps));
}

EnvStep ServoEnv::reset(std::optional<std::uint64_t> seed, std::optional<Eigen::Isometry3d> initial) {
  const sim::Scenario& sc = cell_.scenario;
  if (seed) {
    const auto off = draw_initial_offset(cell_, *seed);
    initial = sim::offset_pose(sc.world_T_desired, {off[0], off[1], off[2]}, {off[3], off[4], off[5]},
                               sc.offset_frame_rotation_deg);
  }
  ExperimentOptions o;
  o.servo = options_.servo;
  o.source = options_.source;
  // the cell's own cap stays above the episode's: truncation is the environment's word
  o.max_iterations = options_.max_steps + 10;
  o.noise_seed = seed.value_or(sc.seed);
  loop_ = std::make_unique<loop::InMemoryLoop>(cell_, experiment_loop_setup(cell_, o, o.noise_seed));
  steps_ = 0;
  done_ = false;
  pending_.reset();
  loop_->command(command(cell_dds::SimCommand::kTeach));
  // the teach frame, answered by the servo (its zero twist), then RESET and START
  for (int round = 0; round < 50; ++round) {
    std::vector<loop::LoopExchange> xs;
    loop_->observe(xs);
    for (const auto& x : xs) {
      loop_->answer(x, x.reply.twist);
      if (!x.frame.teach) continue;
      if (!x.reply.taught) throw std::runtime_error(sc.file.string() + ": the servo was not taught: " + x.reply.reason);
      if (!loop_->command(command(cell_dds::SimCommand::kReset, initial.value_or(sc.world_T_initial()))))
        throw std::runtime_error(sc.file.string() + ": the initial pose was refused");
      loop_->command(command(cell_dds::SimCommand::kStart));
      return next_frame();
    }
  }
  throw std::runtime_error(sc.file.string() + ": no teach frame");
}

EnvStep ServoEnv::step(const control::Vector6d& twist) {
  if (!loop_) throw std::logic_error("step() before reset()");
  if (done_) throw std::logic_error("step() after the episode ended: call reset()");
  for (int i = 0; i < 6; ++i)
    if (!std::isfinite(twist[i]))
      throw std::invalid_argument("twist[" + std::to_string(i) + "] is " + std::to_string(twist[i]) +
                                  ": every component must be finite (m/s, rad/s)");
  loop_->answer(*pending_, twist);
  ++steps_;
  return next_frame();
}

EnvStep ServoEnv::next_frame() {
  EnvStep out;
  pending_.reset();
  bool session_over = false;
  for (int round = 0; round < 1000 && !pending_ && !session_over; ++round) {
    std::vector<loop::LoopExchange> xs;
    session_over = loop_->observe(xs).done;
    for (auto& x : xs) {
      if (!pending_ && x.frame.applies_twist && !x.frame.teach) {
        pending_ = std::move(x);
        continue;
      }
      loop_->answer(x, x.reply.twist);  // a frame no twist moves the robot on: the servo's (zero)
    }
  }
  if (pending_) {
    out.observation = observation_of(*pending_);
    out.reward = -out.observation.error_norm;
  }
  const servo::ServoState state = pending_ ? pending_->reply.state : servo::ServoState::kIdle;
  if (session_over || !pending_) {
    // the cell ended the session (a robot stop: a collision; the servo stopping) or made no frame
    const std::string& why = loop_->cell().session_end().reason;
    out.terminated = true;
    out.reason = why.empty() ? "the cell made no frame" : why;
  } else if (state == servo::ServoState::kConverged) {
    out.terminated = true;
    out.reason = "converged";
  } else if (state == servo::ServoState::kStopped) {
    out.terminated = true;
    out.reason = "the servo stopped: " + pending_->reply.reason;
  } else if (steps_ >= options_.max_steps) {
    out.truncated = true;
    out.reason = "max_steps (" + std::to_string(options_.max_steps) + ")";
  }
  done_ = out.terminated || out.truncated;
  return out;
}

EnvObservation ServoEnv::observation_of(const loop::LoopExchange& x) const {
  EnvObservation o;
  const servo::ServoReply& r = x.reply;
  if (r.step) o.matched = r.step->matched;
  // the reply's counts: the law's step leaves its own at 0 where the servo's node counted
  // (issue 43: info["detected"] was always 0)
  o.detected = r.detected;
  o.decoded = static_cast<int>(r.decoded);
  o.error_norm = r.error_norm;
  o.servo_state = state_name(r.state);
  o.world_T_camera = x.frame.world_T_camera;
  const sim::GoalError goal = sim::goal_error(x.frame.world_T_camera, cell_.scenario.world_T_desired, cell_.goal_plane);
  o.translation_error_m = goal.translation_m;
  o.rotation_error_deg = goal.rotation_rad * 180.0 / M_PI;
  o.time_s = x.frame.time_s;
  o.limited = sim::limit_names(x.frame.robot_limits);
  if (options_.images) o.image = x.image;
  return o;
}

}  // namespace experiment
