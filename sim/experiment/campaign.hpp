// Beyond the paper: the same task from many random initial poses, for each model of the
// interaction matrix. Seeded draws, both cores, a progress line; campaign.csv per run and a
// summary table (convergence rate, median iterations, final errors).
#pragma once

#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "sim/experiment/experiment.hpp"

namespace experiment {

struct CampaignOptions {
  int runs = 20;
  std::vector<control::InteractionModel> models;
  servo::ServoConfig base;
  loop::FeatureSource source = loop::FeatureSource::kDecoded;
  std::uint64_t seed = 1;
  double scale = 1.0;  // initial offsets drawn in [-scale |x|, scale |x|] of the scenario's
  int max_iterations = 400;
  int threads = 2;
  // run the shard_index-th of shard_count slices (1-based): every shard_count-th initial
  // pose; `merge_campaigns` combines the slices into the unsharded result
  int shard_index = 1, shard_count = 1;
  std::filesystem::path out_dir;
  // errors and delays for every run (default: the scenario's); each run draws its own
  // directions of the calibration errors from its seed
  std::optional<sim::CalibrationErrors> errors;
  std::optional<sim::Latency> latency;
  double divergence_ratio = 0;  // as servo::ServoConfig::divergence_ratio, for every run
  double outlier_fraction = 0;  // as ExperimentOptions
  double loss_fraction = 0;     // as ExperimentOptions
  bool white_frame = false;     // as ExperimentOptions
  double white_frame_lead = 0;  // as ExperimentOptions
};

// A median or worst value as the summary tables show it: "-" when no run gave one (not "nan").
std::string table_number(double v, int decimals);


// A hash (16 hex digits, FNV-1a) of the scenario file and of every file it names (meshes,
// pattern, URDF and the URDF's meshes): two shards with the same name: but another scene differ.
std::string scenario_fingerprint(const sim::Scenario& scenario);

// Returns the summary table as Markdown (also written to out_dir/summary.md).
// Writes campaign.csv (one row per run, numbers to 17 digits), campaign.json (what was run)
// and summary.md into out_dir.
std::string run_campaign(const sim::Cell& cell, const CampaignOptions& options);

// Combines the folders of all shards of one campaign into out_dir: the same campaign.csv and
// summary.md as the unsharded run. Throws std::invalid_argument (one line) when the folders
// are not the shards of one campaign, or one is missing or repeated.
std::string merge_campaigns(const std::vector<std::filesystem::path>& shard_dirs, const std::filesystem::path& out_dir);

// Per model, what a campaign folder's runs came to (the summary table's numbers).
struct ModelStats {
  std::string model;
  int runs = 0, converged = 0, diverged = 0;
  int capped = 0, safe_stops = 0;  // stopped by the iteration cap, by a safe stop
  int robot_stops = 0;             // the robot stopped by itself: a collision, a fault
  int rose = 0;  // not stopped as diverging, yet |e| rose: past 2x its first value, or by 1x in all
  double median_iterations = 0, median_translation_mm = 0, median_rotation_deg = 0;  // converged runs
  double worst_translation_mm = 0, worst_rotation_deg = 0;                           // converged runs
  double median_error_rise = 0;                                                      // all runs
  // decoded features: the runs whose law took a point off its spot's centre (the simulator's
  // truth: ExperimentResult::off_centre_max), and the most in one iteration of any run
  int off_centre_runs = 0;
  long long off_centre_max = 0;
};
std::vector<ModelStats> campaign_stats(const std::filesystem::path& dir);

// Runs bin/plot_campaign.py on a campaign folder (campaign.png: per model, the converged share,
// the iterations, the final errors); false, with the reason on stderr, when it cannot.
bool plot_campaign(const std::filesystem::path& dir, const std::string& title);

// One initial offset (x y z cm, rx ry rz deg) drawn as a campaign of that seed draws its first:
// each component in +-scale max(2, |the scenario's|), drawn again until the camera sees 80 %
// of the spots it sees at the desired pose and the arm reaches it.
std::array<double, 6> draw_initial_offset(const sim::Cell& cell, std::uint64_t seed, double scale = 1.0);

}  // namespace experiment
