// The in-process closed loop (no DDS): teach at the desired pose, move to the initial pose,
// servo until convergence, the iteration cap or a safe stop. Simulated time only: each
// iteration is one dt of the scenario, whatever the wall clock does.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "servo/pipeline/servo_pipeline.hpp"
#include "sim/geometry/se3.hpp"
#include "sim/render/renderer.hpp"

namespace cellsim {

enum class FeatureSource { kDecoded, kIdeal };  // ideal: the simulator's true image positions

struct ExperimentOptions {
  servo::ServoConfig servo;
  FeatureSource source = FeatureSource::kDecoded;
  int max_iterations = 400;
  std::optional<Eigen::Isometry3d> initial;  // default: the scenario's initial pose
  std::filesystem::path out_dir;             // trace.csv, features.jsonl (nothing when empty)
  bool write_features = true;
  std::uint64_t noise_seed = 0;              // 0: the scenario's seed
};

struct IterationRecord {
  double t_s = 0;
  sim::Vector6d twist = sim::Vector6d::Zero();
  double error_norm = 0, feature_rms = 0;
  int decoded = 0, matched = 0;
  double translation_error_m = 0, rotation_error_deg = 0;
  std::uint32_t robot_limits = 0;  // why the robot limited this step's motion (sim::RobotLimit bits)
};

struct ExperimentResult {
  bool converged = false;
  std::string stop_reason;
  int iterations = 0;
  int decoded_desired = 0, decoded_initial = 0;
  double final_translation_error_m = 0, final_rotation_error_deg = 0;
  std::vector<IterationRecord> trace;
};

// What calibration would give for a cell, exact: the camera's intrinsics and the projector's
// model (what `cellsim calibration` writes).
control::CameraIntrinsics camera_intrinsics_of(const sim::Cell& cell);
control::ProjectorModel projector_model_of(const sim::Cell& cell);

// The servo configuration a scenario implies: the camera's intrinsics and the projector's
// calibration taken as exact.
servo::ServoConfig servo_config_for(const sim::Cell& cell);

ExperimentResult run_experiment(const sim::Cell& cell, const ExperimentOptions& options);

FeatureSource parse_feature_source(const std::string& name);
std::string to_string(FeatureSource s);

// Runs bin/plot_trace.py on an experiment folder (velocities.png, error_norm.png); returns
// false, with the reason on stderr, when plotting is not possible.
bool plot_experiment(const std::filesystem::path& dir, const std::string& title);
// Runs bin/SCRIPT_NAME DIR --title TITLE with Debian's python3 (matplotlib).
bool run_plot_script(const std::string& script_name, const std::filesystem::path& dir, const std::string& title);

}  // namespace cellsim
