// Campaigns along one or two axes (issue 13): the depth study (Z-hat, the object's depth
// spread), the calibration-error study (an error's magnitude), the latency study (gain x
// delay). Each point of the grid is a whole campaign (the same seeded initial poses for every
// point and model) in its own folder; study.csv and summary.md gather them per model, and
// bin/plot_study.py draws study.png.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "sim/experiment/campaign.hpp"

namespace experiment {

// What an axis can vary:
//   z_hat                      the depth of desired-constant-depth (m)
//   gain                       the constant gain lambda
//   object_scale_x|y|z         every object's mesh scaled along its own axis (the depth
//                              spread the camera sees; study.csv gives it in metres)
//   object_yaw_deg             every object turned about the vertical through its origin
//   any calibration error      focal_pct, hand_eye_rotation_deg, ... (sim::error_names)
//   error_scale                every calibration error given (scenario, --error) times this
//   any delay                  acquisition_frames, processing_frames, actuation_s
//   losses                     the share of the decoded spots dropped at every frame
//   visual_features            points, moments, surface, plane (by name; study.csv holds 0, 1, 2, 3)
struct StudyAxis {
  std::string name;
  std::vector<double> values;
};

// "z_hat=0.3,0.6,0.9" -> the axis; throws std::invalid_argument (one line) for an unknown
// name, a value out of its range, or more than 64 values.
StudyAxis parse_study_axis(const std::string& spec);
std::vector<std::string> study_axis_names();

struct StudyOptions {
  CampaignOptions campaign;     // runs, models, seed, features, the base servo configuration
  std::vector<StudyAxis> axes;  // one or two
  std::filesystem::path out_dir;
};

// Returns the summary (Markdown; also in out_dir/summary.md) and writes study.csv, study.json
// and one campaign folder per grid point.
std::string run_study(const sim::ResolvedScenario& scenario, const StudyOptions& options);

bool plot_study(const std::filesystem::path& dir, const std::string& title);

}  // namespace experiment
