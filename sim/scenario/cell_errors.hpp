// The errors a real cell has and the paper's simulation does not (issue 13): what the servo
// is told is not what the cell is. The simulator keeps the truth (it renders, raycasts and
// moves with it); the servo gets a calibration drawn away from it, and a loop with delays.
// Plain data: the magnitudes come from the scenario (`errors:`, `latency:`) or from flags,
// the directions from a seeded draw (draw_errors), so a campaign over the magnitude sees a
// different direction in every run and the same ones in every repeat.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "sim/robot/robot.hpp"

namespace sim {

// Limits checked at load and for flags (docs/topics.md, Safety).
inline constexpr double kMaxFocalErrorPct = 50, kMaxPrincipalErrorPx = 500, kMaxDistortionError = 1;
inline constexpr double kMaxPositionErrorMm = 500, kMaxRotationErrorDeg = 45;
inline constexpr double kMaxLinkLengthErrorPct = 20, kMaxJointOffsetErrorDeg = 20;
inline constexpr int kMaxDelayFrames = 50;  // bounds the queues of images and twists
inline constexpr double kMaxActuationDelayS = 1.0;

// Magnitudes. Zero everywhere: the servo is told the truth, as before this existed.
struct CalibrationErrors {
  double focal_pct = 0;             // fx and fy each off by this much, each with a drawn sign
  double principal_point_px = 0;    // (cx, cy) off by this much in a drawn direction
  double distortion_k1 = 0;         // k1 off by this much, drawn sign
  double projector_position_mm = 0, projector_rotation_deg = 0;  // drawn direction / axis
  double hand_eye_position_mm = 0, hand_eye_rotation_deg = 0;    // camera on the flange
  double link_length_pct = 0;       // each joint origin's offset scaled by 1 +- this (arm)
  double joint_offset_deg = 0;      // each joint's zero off by +- this (arm)
  std::optional<std::uint64_t> seed;  // the draw; default: the run's seed
  bool any() const;
};

// Delays of the loop. In lockstep the image of frame k is the scene of frame
// k - acquisition_frames (paired with the pose reported at k, as a stamp-less camera would
// be), its twist reaches the robot processing_frames frames later, and the robot starts to
// follow a twist actuation_s after it gets it (holding the previous one until then).
struct Latency {
  int acquisition_frames = 0;
  int processing_frames = 0;
  double actuation_s = 0;
  bool any() const { return acquisition_frames > 0 || processing_frames > 0 || actuation_s > 0; }
};

// One draw of the errors: what the servo believes, relative to the truth.
struct DrawnErrors {
  double fx_scale = 1, fy_scale = 1;
  Eigen::Vector2d principal_shift_px = Eigen::Vector2d::Zero();
  double k1_shift = 0;
  // believed world_T_projector = true world_T_projector * projector_delta
  Eigen::Isometry3d projector_delta = Eigen::Isometry3d::Identity();
  // the hand-eye error and the arm's kinematic errors, for Robot::set_belief
  RobotBelief robot;
};

// Deterministic in (errors, seed, chain_segments); the identity for zero magnitudes.
DrawnErrors draw_errors(const CalibrationErrors& errors, std::uint64_t seed, std::size_t chain_segments);

// "focal_pct=1" style settings, as the `--error` and `--latency` flags take them. Throws
// std::invalid_argument naming the setting for an unknown name or a value out of range.
void set_error(CalibrationErrors& errors, const std::string& assignment);
void set_latency(Latency& latency, const std::string& assignment);
void set_error(CalibrationErrors& errors, const std::string& name, double value);
void set_latency(Latency& latency, const std::string& name, double value);
// The errors and delays as campaign.json and the study tables name them:
// "focal_pct=1 processing_frames=2" ("none" when all are zero).
std::string describe(const CalibrationErrors& errors, const Latency& latency);
// the names set_error and set_latency know
std::vector<std::string> error_names();
// every magnitude with its name, in error_names() order
std::vector<std::pair<std::string, double>> error_values(const CalibrationErrors& errors);
std::vector<std::string> latency_names();

}  // namespace sim
