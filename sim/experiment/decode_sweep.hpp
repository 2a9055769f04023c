// Decoder accuracy against the simulator's ground truth, over random poses and noise levels.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "servo/vision/spot_decoder.hpp"
#include "sim/render/renderer.hpp"

namespace experiment {

struct SweepOptions {
  int poses = 1000;
  std::uint64_t seed = 1;
  std::vector<double> noise_sigmas{0.5, 1.5, 3.0, 6.0};
  vision::DecoderOptions decoder;
  // the projector's calibration: the decoder then checks ids against the epipolar geometry of
  // each pose (the camera's intrinsics are the scenario's, its pose the true one); without it,
  // the ids off the lines fitted to each frame's own spots are marked (mark_off_fitted_lines),
  // as the servo marks them
  std::optional<calibration::ProjectorModel> projector;
  // the camera's crosstalk the decoder is told (SegmentationOptions::crosstalk; with the
  // calibration the segmentation's levels follow it): unset, the scenario camera's; set, a
  // crosstalk calibration off by that much
  std::optional<double> told_crosstalk;
  // with the calibration: the servo holds each id to its taught point (ServoConfig::taught_points,
  // servo/pipeline/taught_points.hpp), and the ids it keeps out do not reach the law
  bool taught_points = false;
  // beside each pattern frame the camera takes the white reference frame at the same pose, and
  // the decoder reads their ratio (vision::normalise_by_white): the surface's albedo divided out
  bool white_frame = false;
  double match_tolerance_px = 2.0;
  std::filesystem::path out_dir;   // sweep.csv (and failure overlays) go here when set
  int threads = 2;
  // the draw: each offset component uniform in +-this (default: the scenario's initial offset
  // per axis, at least 2 cm / 2 deg); issue 19 widens it to find rare wrong ids
  std::optional<double> max_translation_cm, max_rotation_deg;
};

// Why a readable spot segmented as a blob of its colour was not identified (the first that
// applies): its blob named another id; cut by the image border (never reported); no step 6
// (no calibration); named, then dropped (step 5's islands after step 6, or the report's
// fragment and speck tests); step 6's refusal (vision::GrowthOutcome); no identified spot
// among its 8 pattern neighbours; none of their predictions landed on it.
enum LossCause {
  kLostOtherId, kLostBorder, kLostNoGrowth, kLostDropped, kLostUnlikeClaim, kLostDissent, kLostNoDirectSource,
  kLostFewSources, kLostUnlikeSources, kLostTaken, kLostResidual, kLostNeighbourFits, kLostNearerLine, kLostNearerBlob,
  kLostAlone, kLostUnclaimed, kLossCauses
};
// the CSV column of each cause
inline constexpr std::array<const char*, kLossCauses> kLossCauseNames{
    "lost_other_id",     "lost_border",      "lost_no_growth",     "lost_dropped",
    "lost_unlike_claim", "lost_dissent",     "lost_no_direct",     "lost_few_sources",
    "lost_unlike_sources", "lost_taken",     "lost_residual",      "lost_neighbour_fits",
    "lost_nearer_line",  "lost_nearer_blob", "lost_alone",       "lost_unclaimed"};

struct SweepRow {
  int pose = 0;
  double noise_sigma = 0;
  std::array<double, 6> offset{};  // cm, cm, cm, deg, deg, deg from the desired pose
  // wrong: the id names another spot (the visible spot nearest the decoded position has a
  // different id, or that id is not visible); mislocated: right id, centroid off by more than
  // the match tolerance
  // partial: the named spot's centre is hidden but the decoded blob is its light (a spot split
  // by a depth edge, or cut by an occluding contour): the right id, its centroid not the centre
  int visible = 0, detected = 0, decoded = 0, correct = 0, wrong = 0, mislocated = 0, partial = 0;
  // of the partial ids, those whose four pattern neighbours are named in the frame too: at most
  // these reach the law with `--interior-points` (control::interior_points keeps the matched
  // spots whose four neighbours are matched, when they are half the matched set or more)
  int partial_interior = 0;
  // With the calibration, the ids the decoder found off their epipolar lines and keeps from the
  // control law (DecodedSpot::off_line), in all and by what the truth says they are
  int off_line = 0, off_line_right = 0, off_line_mislocated = 0, off_line_partial = 0, off_line_wrong = 0;
  // The ids that reach the control law, in all and by what the truth says they are: on their
  // lines, and taught: the law matches s with s* by id, and s* holds the ids the servo named on
  // their lines at the desired pose (SweepSummary::taught, decoded as the sweep decodes)
  int to_law = 0, to_law_right = 0, to_law_mislocated = 0, to_law_partial = 0, to_law_wrong = 0;
  // With SweepOptions::taught_points, the ids on their lines and in s* that lie away from their
  // taught point, kept from the law, by what they are
  int off_taught = 0, off_taught_right = 0, off_taught_mislocated = 0, off_taught_partial = 0, off_taught_wrong = 0;
  // decodable: visible, and in some 3 x 3 window of the pattern whose nine spots are all
  // visible (its id can be read from what the camera sees); correct_decodable: of those, the
  // ones decoded right
  int decodable = 0, correct_decodable = 0;
  // resolved: visible and not washed out by the projector's defocus (SpotTruth::resolved);
  // readable: resolved, in some 3 x 3 window whose nine spots are all resolved
  int resolved = 0, readable = 0, correct_readable = 0;
  // where the readable spots are lost, step by step: segmented (a blob of the spot's colour
  // within the match tolerance), linked (its four links, where the pattern has a neighbour, go
  // to the blobs of the true neighbours), windowed (its 8-neighbourhood after the graph check
  // is complete and right)
  int readable_segmented = 0, readable_linked = 0, readable_windowed = 0;
  // readable on one object: in a fully resolved 3 x 3 window whose nine spots all land on one
  // object. A window across the ham's silhouette (its rows on the ham, on the table) is
  // readable, but no lattice shows it: its spots on the two surfaces lie apart in the image
  int readable_one_object = 0, correct_readable_one_object = 0;
  // readable and apart in the image: no other visible spot's disc overlaps its own (centres
  // at least the two discs' radii apart). Towards a silhouette the surface turns away and the
  // columns crowd together in the image: the projector's focus leaves them spots, the camera's
  // own sampling merges them (on the cylinder, half the readable spots the decoder misses)
  int readable_apart = 0, correct_readable_apart = 0;
  // why each readable spot segmented as a blob of its colour has no id (LossCause order)
  std::array<int, kLossCauses> lost{};
  double decode_ms = 0;
};

struct SweepSummary {
  std::vector<SweepRow> rows;
  int total_decoded = 0, total_wrong = 0, total_visible = 0, total_mislocated = 0, total_partial = 0;
  int total_partial_interior = 0;
  int total_off_line = 0, total_off_line_right = 0, total_off_line_mislocated = 0, total_off_line_partial = 0,
      total_off_line_wrong = 0;
  int total_to_law = 0, total_to_law_right = 0, total_to_law_mislocated = 0, total_to_law_partial = 0,
      total_to_law_wrong = 0;
  int total_off_taught = 0, total_off_taught_right = 0, total_off_taught_mislocated = 0, total_off_taught_partial = 0,
      total_off_taught_wrong = 0;
  int taught = 0;  // the ids of s*: named on their lines at the desired pose
  int total_decodable = 0, total_correct = 0, total_correct_decodable = 0;
  int total_resolved = 0, total_readable = 0, total_correct_readable = 0;
  int total_readable_segmented = 0, total_readable_linked = 0, total_readable_windowed = 0;
  int total_readable_one_object = 0, total_correct_readable_one_object = 0;
  int total_readable_apart = 0, total_correct_readable_apart = 0;
  std::array<int, kLossCauses> total_lost{};
  double mean_rate = 0, min_rate = 1;
  double mean_decodable_rate = 0;  // mean over poses of correct_decodable / decodable
  double mean_readable_rate = 0;   // mean over poses of correct_readable / readable
  double mean_readable_one_object_rate = 0;
  double mean_readable_apart_rate = 0;
  double median_ms = 0, p99_ms = 0;
};

// Poses: every component of the scenario's initial offset drawn uniformly in [-|x|, |x|]
// (at least 2 cm / 2 deg), i.e. within the paper's displacements for that experiment.
SweepSummary run_decode_sweep(const sim::Cell& cell, const SweepOptions& options);

}  // namespace experiment
