// The cell as an environment for a controller of the user's (issue 22, the Python API's
// ServoEnv): the in-memory loop (the services' own state machines) with the servo's twist
// replaced by the caller's. reset() teaches at the desired pose, sends the robot to an
// initial pose (the scenario's, or a seeded draw as a campaign draws them) and starts;
// step(twist) answers the latest frame with the caller's twist and returns the next one.
// The observation is what the servo sees: the decoded features matched to s* (and the image
// when asked for); the reward is -|e|, the norm of the task function the servo computes with
// its model; the episode terminates when the servo reports convergence or the cell ends the
// session (a robot stop: a collision; the servo stopping), and is truncated at max_steps.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sim/experiment/experiment.hpp"
#include "sim/loop/in_memory_loop.hpp"

namespace experiment {

struct EnvOptions {
  servo::ServoConfig servo;  // the servo's configuration (its law gives the reward's |e|)
  loop::FeatureSource source = loop::FeatureSource::kDecoded;
  int max_steps = 300;       // truncated after this many steps
  bool images = false;       // keep each frame's image in the observation
};

struct EnvObservation {
  std::vector<control::MatchedPoint> matched;  // s and s* by spot id (normalised; depths when known)
  cv::Mat image;                               // RGB, when EnvOptions::images
  int detected = 0, decoded = 0;
  double error_norm = 0;
  Eigen::Isometry3d world_T_camera = Eigen::Isometry3d::Identity();  // the truth (info, not for the controller)
  double translation_error_m = 0, rotation_error_deg = 0;            // to the desired pose (info)
  double time_s = 0;
  std::string servo_state;  // idle, teaching, servoing, converged, lost, stopped
  // why the robot did not make the last twist as given ("cartesian_speed", "joint_velocity|...",
  // sim::limit_names; "" when it did): a 10 m/s twist is clipped to the cell's speed, and says so
  std::string limited;
};

struct EnvStep {
  EnvObservation observation;
  double reward = 0;
  bool terminated = false, truncated = false;
  std::string reason;  // why it terminated or was truncated
};

class ServoEnv {
 public:
  ServoEnv(const sim::Cell& cell, EnvOptions options);

  // A new episode. `seed`: the initial pose drawn as a campaign draws it (each component of
  // the scenario's displacement in +-max(2, |value|)); none: `initial`, or the scenario's.
  // Throws std::runtime_error when the servo cannot be taught or the pose is refused.
  EnvStep reset(std::optional<std::uint64_t> seed = std::nullopt,
                std::optional<Eigen::Isometry3d> initial = std::nullopt);
  // One step with the caller's camera twist (vx vy vz wx wy wz, m/s and rad/s, camera frame).
  // Throws std::invalid_argument for a non-finite twist, std::logic_error before reset() or
  // after the episode ended.
  EnvStep step(const control::Vector6d& twist);

  const sim::Cell& cell() const { return cell_; }
  int steps() const { return steps_; }

 private:
  // rounds until a frame whose twist moves the robot (or the session's end)
  EnvStep next_frame();
  EnvObservation observation_of(const loop::LoopExchange& x) const;

  const sim::Cell& cell_;
  EnvOptions options_;
  std::unique_ptr<loop::InMemoryLoop> loop_;
  std::optional<loop::LoopExchange> pending_;  // the frame the next step answers
  int steps_ = 0;
  bool done_ = true;
};

}  // namespace experiment
