// One controller iteration, as both the in-process runner and the `servo` service run it:
// image -> spots (decoder) -> features s (normalised, matched by id with s*) -> depths
// (triangulation, when the model needs them) -> twist (control law).
// Pure with respect to time and transport: the caller passes the image and, when it has
// one, the camera pose the robot reports.
#pragma once

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "servo/calibration/camera_intrinsics.hpp"
#include "servo/control/control_law.hpp"
#include "servo/control/triangulation.hpp"
#include "servo/pipeline/taught_points.hpp"
#include "servo/vision/spot_decoder.hpp"

namespace servo {

struct ServoConfig {
  vision::DecoderOptions decoder;
  control::ControlLawOptions law;
  calibration::CameraIntrinsics camera;
  // the calibrated projector: needed to triangulate depths (models desired, current, mean)
  std::optional<calibration::ProjectorModel> projector;
  // Point selection (issue 13, item 5): > 0 servos on this many points, chosen at teaching
  // for the best-conditioned interaction matrix (control::best_conditioned_subset); 0: all.
  int points = 0;
  // Servo on the interior of the matched set (control::interior_points): the spots whose four
  // pattern neighbours are matched too, when they are at least `interior_min_share` of it.
  // Measured on the tuning scenes' closed loops (docs/results.md): the egg's and the
  // cylinder's median final error 0.46 -> 0.13 mm and 0.17 -> 0.11 mm, the plane's and the ham's
  // the same. Below half, the matched set is mostly edge (a sparse decoding) and all serve.
  bool interior_points = false;
  double interior_min_share = 0.5;
  // With the projector's calibration (static: not riding on the camera; refused at start
  // otherwise) and the camera's pose: each id held to the point its spot lit at teaching
  // (taught_points.hpp); a spot away from its taught point's projection is no feature.
  // Measured (docs/decoding.md, What reaches the control law; docs/results.md): of the spills
  // that reach the law, 14 of 16 held out on the tuning sweeps and the sphere's and step's
  // all, for 0.5 % of the right ids; ids swapped at every frame held out up to 30 % of them.
  // Off by default: the egg's loop ends farther, and the paper's law takes every matched spot.
  bool taught_points = false;
  // Each image decoded as its ratio to the white reference frame of the same stamp (the
  // projector casting white: vision/reference.hpp), the surface's albedo divided out; an image
  // without one is rejected. Measured (docs/decoding.md, Appearance): a printed box's ids
  // 22 -> 67 at the initial pose, its 24 closed loops 14 -> 24 converged; more wrong ids at
  // depth edges (held out 8 -> 17), so off by default.
  bool white_frame = false;
  // > 0: the servo stops (zero twist, state STOPPED, reason "diverging") when |e| rises above
  // this x its first value after START or teaching (issue 13); 0: never
  double divergence_ratio = 0;
  // a safe stop lasting this many frames in a row stops the servo (control::SafeStopWatch)
  int safe_stop_frames = 25;
};

// A spot located in the image with its identity: from the decoder, or from the simulator's
// truth for the `ideal` feature source.
struct ImageSpot {
  int row = 0, col = 0;
  double u = 0, v = 0;
  // the decoder found it off its id's epipolar line (vision::DecodedSpot::off_line), or its
  // blob clipped (vision::DecodedSpot::clipped): the right id, but not where the spot's centre
  // is; it is no feature of the law
  bool off_line = false, clipped = false;
  bool apart() const { return off_line || clipped; }
};

// A decoded spot as the servo locates it (ServoPipeline::locate's output, and the sweeps' view of
// it): one conversion, so that what keeps a spot from the law cannot differ between them.
inline ImageSpot image_spot(const vision::DecodedSpot& d) { return {d.row, d.col, d.u, d.v, d.off_line, d.clipped}; }

struct StepResult {
  int detected = 0;                         // blobs segmented (0 for the ideal source)
  int decoded = 0;                          // spots with an id
  std::vector<control::Feature> features;   // normalised, depth when triangulated
  std::vector<control::MatchedPoint> matched;
  control::ControlOutput control;
  int held_by_taught = 0;                   // features away from their taught points (taught_points)
};

class ServoPipeline {
 public:
  ServoPipeline(pattern::WindowTable table, ServoConfig config);

  // Decodes an image into identified spots. With a camera pose and the projector's
  // calibration, the decoder also checks ids along the epipolar lines and grows the
  // identified lattice; without them, the spots off the lines fitted to the frame's own spots
  // are marked off_line (vision::mark_off_fitted_lines), as the calibration's lines mark them.
  // `white` (optional): the white reference frame taken at the same pose, the pattern frame
  // decoded as its ratio to it (vision/reference.hpp). Throws std::invalid_argument for a bad
  // image, or a white frame that is not the image's size.
  // `scratch` (optional): the decoder's room, reused from the caller's last frame.
  std::vector<ImageSpot> locate(const cv::Mat& rgb, const std::optional<Eigen::Isometry3d>& world_T_camera,
                                int* detected = nullptr, const cv::Mat* white = nullptr,
                                vision::DecodeScratch* scratch = nullptr) const;

  // Features of located spots: normalised coordinates and, when a camera pose and the
  // projector's calibration are known, triangulated depths. None of a spot off its line.
  std::vector<control::Feature> features(const std::vector<ImageSpot>& spots,
                                         const std::optional<Eigen::Isometry3d>& world_T_camera) const;

  // Teach-by-showing: the features seen now become s* (and, with taught_points, the points
  // their spots light).
  int teach(const std::vector<ImageSpot>& spots, const std::optional<Eigen::Isometry3d>& world_T_camera);
  // s* given (loaded from a file): no pose was seen with it, so no point is held
  void set_reference(std::vector<control::Feature> s_star) {
    reference_ = std::move(s_star);
    taught_.clear();
  }
  const std::vector<control::Feature>& reference() const { return reference_; }
  bool taught() const { return !reference_.empty(); }

  // With taught_points, taught and given a pose: which of `features` lie away from their
  // taught points (taught_points.hpp); otherwise nothing is held.
  TaughtCheck hold_to_taught(const std::vector<control::Feature>& features,
                             const std::optional<Eigen::Isometry3d>& world_T_camera) const;

  // One iteration of the control law from located spots.
  StepResult step(const std::vector<ImageSpot>& spots, const std::optional<Eigen::Isometry3d>& world_T_camera) const;

  const ServoConfig& config() const { return config_; }
  ServoConfig& config() { return config_; }

 private:
  vision::SpotDecoder decoder_;
  ServoConfig config_;
  std::vector<control::Feature> reference_;
  std::vector<std::pair<int, int>> selected_;  // the (row, col) ids chosen at teaching, sorted
  std::vector<TaughtPoint> taught_;            // with taught_points: the points s*'s spots lit
};

}  // namespace servo
