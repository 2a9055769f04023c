// Beyond the paper: the same task from many random initial poses, for each model of the
// interaction matrix. Seeded draws, both cores, a progress line; campaign.csv per run and a
// summary table (convergence rate, median iterations, final errors).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "sim/app/experiment.hpp"

namespace cellsim {

struct CampaignOptions {
  int runs = 20;
  std::vector<control::InteractionModel> models;
  servo::ServoConfig base;
  FeatureSource source = FeatureSource::kDecoded;
  std::uint64_t seed = 1;
  double scale = 1.0;  // initial offsets drawn in [-scale |x|, scale |x|] of the scenario's
  int max_iterations = 400;
  int threads = 2;
  std::filesystem::path out_dir;
};

// Returns the summary table as Markdown (also written to out_dir/summary.md).
std::string run_campaign(const sim::Cell& cell, const CampaignOptions& options);

}  // namespace cellsim
