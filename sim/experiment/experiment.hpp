// The in-process closed loop (no DDS): teach at the desired pose, move to the initial pose,
// servo until convergence, the iteration cap or a safe stop. Simulated time only: each
// iteration is one dt of the scenario, whatever the wall clock does.
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "servo/pipeline/servo_pipeline.hpp"
#include "sim/loop/in_memory_loop.hpp"
#include "sim/geometry/se3.hpp"
#include "sim/render/renderer.hpp"

namespace experiment {

struct ExperimentOptions {
  servo::ServoConfig servo;
  loop::FeatureSource source = loop::FeatureSource::kDecoded;
  int max_iterations = 400;
  std::optional<Eigen::Isometry3d> initial;  // default: the scenario's initial pose
  std::filesystem::path out_dir;             // trace.csv, features.jsonl (nothing when empty)
  bool write_features = true;
  std::uint64_t noise_seed = 0;              // 0: the scenario's seed
  // what the servo is told against the truth, and the loop's delays (default: the scenario's)
  std::optional<sim::CalibrationErrors> errors;
  std::optional<sim::Latency> latency;
  // outlier injection (issue 19): at every frame the ids of this fraction of the spots are
  // swapped among them, a cycle, so each of them is matched wrongly; seeded by the run's seed
  double outlier_fraction = 0;
  double loss_fraction = 0;  // decoded spots dropped at every frame (loop::LoopSetup::loss_fraction)
  bool white_frame = false;  // the white reference frame beside each pattern frame (loop::LoopSetup)
  double white_frame_lead = 0;  // taken this share of a frame period before it (loop::LoopSetup)
  // everything the loop passes, as the wire would carry it (cellsim experiment --record)
  loop::LoopTap* tap = nullptr;
  // the renderer's threads: 0 OpenCV's pool (cv::setNumThreads), 1 the run's own thread only
  // (campaigns, whose runs already keep every core busy)
  int render_threads = 0;
  // asked once a round: true stops the run there, stop reason "cancelled" (Python's Ctrl-C)
  std::function<bool()> cancelled;
  // progress of the iterations on stderr (common/progress.hpp): `cellsim experiment` alone, not
  // the runs of a campaign, which says its own
  bool progress = false;
};

struct IterationRecord {
  double t_s = 0;
  sim::Vector6d twist = sim::Vector6d::Zero();
  double error_norm = 0, feature_rms = 0;
  int decoded = 0, matched = 0;
  double translation_error_m = 0, rotation_error_deg = 0;
  std::uint32_t robot_limits = 0;  // why the robot limited this step's motion (sim::RobotLimit bits)
  int swapped = 0;                 // spots given a wrong id by the outlier injection
  // decoded features: of the points the law took, those more than 2 px from the true centre of
  // the spot their id names, or whose spot the camera does not see (a wrong id, a spill, a
  // split spot: the simulator's truth, which the servo never sees)
  int off_centre = 0;
  double condition = 0;            // the condition number of the law's interaction matrix (0: no law step)
};

// How a run ended, in the words of the exit-code table (common/exit_codes.hpp)
enum class RunEnding { kConverged, kDiverged, kCapped, kStopped, kNotTaught, kRefused };

struct ExperimentResult {
  RunEnding ending = RunEnding::kStopped;
  bool converged = false;
  bool diverged = false;
  // the robot stopped by itself (a collision: "robot stop: collision: link 'A' touches object
  // 'B' (d mm deep)", a fault) and the run ended there (issue 20)
  bool robot_stopped = false;
  std::string stop_reason;
  int iterations = 0;
  int decoded_desired = 0, decoded_initial = 0;
  double final_translation_error_m = 0, final_rotation_error_deg = 0;
  // the camera's path from the initial pose (its length, m) and the straight line to the goal
  double path_length_m = 0, straight_line_m = 0;
  // the law's interaction matrix over the run: its condition number's median and largest
  double condition_median = 0, condition_max = 0;
  // how much |e| rose on its way, summed over the iterations where it rose, relative to its
  // first value: 0 for a monotonic decrease; an oscillating loop piles it up
  double error_rise = 0;
  // the largest |e| of the run over its first: > 1 when the error ever rose above where it began
  double max_error_ratio = 0;
  // IterationRecord::off_centre over the run: the most in one iteration, and the sum
  int off_centre_max = 0;
  long long off_centre_total = 0;
  std::vector<IterationRecord> trace;
};

// What calibration would give for a cell, exact: the camera's intrinsics and the projector's
// model (what `cellsim calibration` writes).
calibration::CameraIntrinsics camera_intrinsics_of(const sim::Cell& cell);
calibration::CameraIntrinsics camera_intrinsics_of(const sim::CameraSpec& camera);
calibration::ProjectorModel projector_model_of(const sim::Cell& cell);

// The servo configuration a scenario implies: the camera's intrinsics and the projector's
// calibration taken as exact.
servo::ServoConfig servo_config_for(const sim::Cell& cell);

// The features `name` names, or for "" the scenario's: points, or the plane when the projector
// rides on the camera (its spots show the surface and nothing more). Throws for a bad name.
control::VisualFeatures visual_features_or_default(const std::string& name, const servo::ServoConfig& config);

// Z-hat by default: the mean depth, at the desired pose, of the spots the camera sees.
double desired_depth(const sim::Cell& cell);

// What calibration would give with the drawn errors (issue 13): the projector's pose as the
// servo is told it (the camera's: sim::believed_camera).
calibration::ProjectorModel believed_projector(const calibration::ProjectorModel& truth, const sim::DrawnErrors& errors);

ExperimentResult run_experiment(const sim::Cell& cell, const ExperimentOptions& options);
// The loop an experiment runs on: the scenario with the options' errors and delays, the
// robot and the servo's belief drawn from `seed`.
loop::LoopSetup experiment_loop_setup(const sim::Cell& cell, const ExperimentOptions& options, std::uint64_t seed);

loop::FeatureSource parse_feature_source(const std::string& name);
std::string to_string(loop::FeatureSource s);

// Runs bin/plot_trace.py on an experiment folder (velocities.png, error_norm.png); returns
// false, with the reason on stderr, when plotting is not possible.
bool plot_experiment(const std::filesystem::path& dir, const std::string& title);
// Runs bin/SCRIPT_NAME DIR --title TITLE with Debian's python3 (matplotlib).
bool run_plot_script(const std::string& script_name, const std::filesystem::path& dir, const std::string& title);

}  // namespace experiment
