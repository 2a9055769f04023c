// The `servo run` service: decodes the camera's images, runs the control law and publishes
// the camera twist, the decoded spots and its status over DDS.
#pragma once

#include "dds/participant.hpp"

#include <filesystem>
#include <memory>
#include <string>

#include "servo/pattern/marray.hpp"
#include "servo/calibration/projector_calibration.hpp"
#include "servo/pipeline/servo_pipeline.hpp"
#include "servo/service/servo_replay.hpp"

namespace servo {

struct ServiceOptions {
  std::filesystem::path pattern;
  ServoConfig config;              // camera intrinsics come from rt/camera/camera_info
  int domain_id = 0;
  cell_dds::Discovery discovery;
  cell_dds::Security security;  // ROS 2's ROS_SECURITY_* variables
  std::string ns;  // ROS 2 namespace of the cell's topics (--namespace); empty: none  // the range and static peers (ROS 2's variables, or the flags)
  double lost_ms = 500;            // no image for this long: zero twist and state LOST
  std::filesystem::path reference; // s*: loaded at start when it exists, saved after teaching
  bool autostart = false;          // servo as soon as a reference exists (no START needed)
  CommandSource commands = CommandSource::kSimulator;
};

int run_servo_service(const ServiceOptions& options);

// The pipeline for `pattern` (checked against the projector's calibration, when there is
// one), with s* from `reference` when that file is given and exists.
std::unique_ptr<ServoPipeline> make_pipeline(const std::filesystem::path& pattern, const ServoConfig& config,
                                             const std::filesystem::path& reference);

// s* as `servo run --reference` writes it after teaching (JSON list of features). Throws
// std::runtime_error naming the file.
std::vector<control::Feature> load_reference(const std::filesystem::path& file);

// The decoder separates the projector's three primaries; a pattern of more colours would
// decode to nothing, so it is refused at load.
inline constexpr int kDecodableColours = 3;
// Reads a pattern file for decoding: the window property and the colour count checked.
pattern::MArray load_decodable_pattern(const std::filesystem::path& file);

// Reads a servo configuration (YAML: model, z_hat_m, gain, gain_adaptive [l0, linf, slope],
// max_linear_mps, max_angular_dps, min_points, converge_mm, converge_deg, min_votes,
// min_island, tolerant, crosstalk, points, interior_points, divergence_ratio, robust,
// visual_features, fitted_lines, white_frame, and with --projector epipolar_px, segment_length,
// propagate_sources, taught_points; servo/service/servo.yaml shows them) over `config`. Throws
// std::runtime_error naming file and key.
void load_servo_config(const std::filesystem::path& file, ServoConfig& config);


}  // namespace servo
