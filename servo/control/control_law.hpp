// Image-based visual servoing (paper eqs. 3-4, Espiau-Chaumette-Rives):
//   e = L-hat^+ (s - s*),   v = -lambda e
// with L-hat one of the InteractionModel choices, a robust pseudo-inverse (SVD, small singular
// values dropped), a constant or adaptive gain, a saturation that keeps the screw's direction,
// a convergence test and a safe stop when too few points are matched. Pure functions of
// their inputs: the caller owns time and state.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "servo/control/image_moments.hpp"
#include "servo/control/interaction_matrix.hpp"
#include "servo/control/surface_features.hpp"

namespace control {

// One matched point: s and s* for the same spot id, with whatever depths are known.
struct MatchedPoint {
  int row = 0, col = 0;
  double x = 0, y = 0;             // current normalised coordinates
  double x_star = 0, y_star = 0;   // desired
  std::optional<double> z;         // current depth (m), e.g. triangulated
  std::optional<double> z_star;    // desired depth (m)
  // a spot cast by a projector riding on the camera: its ray's direction in the camera frame
  // (fixed: the same at s and s*); its rows are then riding_point_interaction_matrix's
  std::optional<Eigen::Vector3d> ray;
};

// A feature with its id, as the decoder gives it (normalised).
struct Feature {
  int row = 0, col = 0;
  double x = 0, y = 0;
  std::optional<double> z;
  std::optional<Eigen::Vector3d> ray;  // as MatchedPoint::ray
};

// s and s* matched by spot id: only spots present in both, in s*'s order.
std::vector<MatchedPoint> match_features(const std::vector<Feature>& current, const std::vector<Feature>& desired);

// The interior of the matched set: the points whose four pattern neighbours (row +-1, col +-1)
// are matched too, in `matched`'s order. At the edge of what is matched lie the spots split by a
// silhouette or a shadow, whose centroid is off their centre and whose neighbours come and go
// from frame to frame; inside it the spots are whole. Returns `matched` itself when the interior
// is under `min_share` of it or under `min_count` points: a sparse decoding (a printed object)
// is mostly edge, and every point is needed there.
std::vector<MatchedPoint> interior_points(const std::vector<MatchedPoint>& matched, double min_share, int min_count);

// lambda(|e|) = (l0 - linf) exp(-l0' |e| / (l0 - linf)) + linf; constant when l0 == linf.
struct Gain {
  double lambda_zero = 0.5;      // gain at |e| = 0
  double lambda_inf = 0.5;       // gain far from the goal
  double slope_zero = 0.0;       // l0': slope of lambda at |e| = 0 (adaptive when > 0)
  double at(double error_norm) const;
  bool adaptive() const { return lambda_zero != lambda_inf; }
};

// M-estimators for the robust law (issue 19; Comport, Marchand & Chaumette 2006, ViSP's
// vpRobust): each point's weight from its residual, the scale from the median absolute
// deviation of the residuals.
enum class RobustEstimator { kNone, kTukey, kHuber };
RobustEstimator parse_robust_estimator(const std::string& name);  // "none" | "tukey" | "huber"; throws
std::string to_string(RobustEstimator e);

// The weights of `residuals` (non-negative: each point's residual norm) under `e`, with the
// scale sigma = 1.4826 x the median absolute deviation from their median, floored at
// `min_scale` so that a converged loop's noise is not taken for outliers:
//   Tukey, c = 4.6851: w = (1 - (r / (c sigma))^2)^2 for |r| < c sigma, else 0
//   Huber, c = 1.345:  w = 1 for |r| <= c sigma, else c sigma / |r|
// with r the residual's deviation from the median. kNone: all 1.
std::vector<double> robust_weights(RobustEstimator e, const std::vector<double>& residuals, double min_scale);

struct ControlLawOptions {
  InteractionModel model = InteractionModel::kDesiredConstantDepth;
  double z_hat_m = 0.9;               // the depth of kDesiredConstantDepth
  Gain gain;
  double max_linear_mps = 0.3;        // the screw is scaled, not clipped per axis
  double max_angular_radps = 0.5;
  int min_points = 4;                 // fewer matched points: safe stop
  double svd_relative_threshold = 1e-6;  // singular values below this x the largest are dropped
  // Converged when the task function e = L-hat^+ (s - s*), a least-squares estimate of the
  // pose error (metres, radians), is below both: the image noise averages out over the points,
  // so this is a finer and steadier test than the feature error itself.
  double convergence_translation_m = 2e-4;
  double convergence_rotation_rad = 4e-4;
  // The robust law v = -lambda (W L-hat)^+ W (s - s*), W diagonal, one weight per point on
  // both of its rows (issue 19): a second line of defence against a wrong match. The weights
  // come by iteratively reweighted least squares: a point's residual is what the motion
  // estimated from the others leaves of its error, (s - s*) - L-hat e, so a point that moves
  // against the rigid motion of the rest is the outlier, wherever it lies in the image.
  RobustEstimator robust = RobustEstimator::kNone;
  // What s is (issue 44): every point's (x, y), the six image moments of the matched points
  // (image_moments.hpp), their interaction matrix from the points' with the model's depths, or
  // the plane of the triangulated points with three moments (surface_features.hpp: it needs
  // every point's current and desired depth, whatever the model; the model says where L is
  // taken: at s* for the desired ones, at s for current, their mean for mean).
  // The task function e = L-hat^+ (s - s*) is a pose error estimate either way, so the
  // convergence test and the gain keep their meaning. Robust weights are per point: points only.
  VisualFeatures features = VisualFeatures::kPoints;
  int robust_iterations = 4;
  double robust_min_scale = 2e-4;  // normalised image units: ~0.16 px at 800 px focal length
};

enum class ControlStatus { kServoing, kConverged, kTooFewPoints, kNoDepth };

struct ControlOutput {
  Vector6d twist = Vector6d::Zero();  // camera frame, (vx vy vz wx wy wz)
  Vector6d task = Vector6d::Zero();   // e = L-hat^+ (s - s*)
  double error_norm = 0;              // |e|, the paper's "norm of the task function"
  double feature_rms = 0;             // RMS of s - s* per coordinate
  double gain = 0;
  int points = 0;
  bool saturated = false;
  // the condition number of the interaction matrix the task came from (the weighted one with
  // the robust law); 0 when none was made (a safe stop)
  double condition = 0;
  ControlStatus status = ControlStatus::kServoing;
  std::string reason;                 // why it stopped, when it did
  // per input point, the depth the model used (kMean: the current one); NaN for points it
  // could not use (no depth)
  std::vector<double> z_model;
  // per input point, its weight in the robust law (1 without one); NaN for points not used
  std::vector<double> weights;
};

// Throws std::invalid_argument (one line) when the options are malformed (non-positive gains,
// limits or z_hat; robust weights with the moments): what compute_control checks first, for
// a configuration to be refused when it is read.
void check_options(const ControlLawOptions& params);

// Throws std::invalid_argument when a matched point has non-finite coordinates or the
// parameters are malformed (non-positive gains, limits or z_hat).
ControlOutput compute_control(const std::vector<MatchedPoint>& points, const ControlLawOptions& params);

// Moore-Penrose pseudo-inverse by SVD, dropping singular values below rel x the largest.
Eigen::MatrixXd pseudo_inverse(const Eigen::MatrixXd& A, double rel);
// A^+ b, the same thresholding, without forming A^+: what the control law uses every iteration.
// `condition` (optional): A's condition number, its largest singular value over its smallest
// (infinity when A is singular), read off the same decomposition; over the `rank` largest (and
// no more than A has rows): the degrees of freedom the features can see (3 for spots cast from
// the camera: the plane's), so that the directions they never see do not make it infinite.
Eigen::VectorXd pseudo_inverse_solve(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, double rel,
                                     double* condition = nullptr, Eigen::Index rank = 6);

// Beyond the paper's experiments (§6, after [6]): choose `count` points greedily so that the
// interaction matrix built from them is as well conditioned as possible.
std::vector<MatchedPoint> best_conditioned_subset(const std::vector<MatchedPoint>& points, std::size_t count,
                                                  const ControlLawOptions& params);

std::string to_string(ControlStatus s);

// A loop that runs away (issue 13): |e| above `ratio` x its first value since reset(). The
// in-process runner and the servo node stop on it; ratio 0 never trips.
// A safe stop (too few points, no depth) gives a zero twist and the loop keeps trying: the next
// frame may see enough again (an occluder moves on). One that lasts `frames` frames in a row
// ends it: in lockstep nothing moves while the twist is zero, so it would last for ever. The
// in-process runner ends the run there and the servo service goes STOPPED, with the same
// reason (issue 20: they used to disagree, the runner ending at the first safe stop and the
// service never). 0: never.
class SafeStopWatch {
 public:
  explicit SafeStopWatch(int frames = 25) : frames_(frames) {}
  void reset() { run_ = 0; }
  // after each step: true once the safe stops have lasted `frames` frames in a row
  bool lasting(ControlStatus status) {
    run_ = status == ControlStatus::kServoing || status == ControlStatus::kConverged ? 0 : run_ + 1;
    return frames_ > 0 && run_ >= frames_;
  }
  int frames() const { return frames_; }

 private:
  int frames_;
  int run_ = 0;
};

class DivergenceWatch {
 public:
  explicit DivergenceWatch(double ratio = 0) : ratio_(ratio) {}
  void reset() { first_.reset(); }
  // "" while the loop is fine; once |e| has run away, why ("diverging: |e| = ...")
  std::string check(double error_norm);

 private:
  double ratio_;
  std::optional<double> first_;
};

}  // namespace control
